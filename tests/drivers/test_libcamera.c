/* libcamera driver: the shim builds and links (this program exists), and with
 * no camera the open fails cleanly with "no cameras". Skips if a camera is
 * present (capture needs hardware; see docs/drivers.md). */
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/driver.h"

int main(void) {
    CHECK(sooc_sensor_has_driver("libcamera"));
    sooc_sensor_params p;
    sooc_sensor_params_default(&p);
    sooc_sensor *s = NULL;
    double t0 = sooc_seconds();
    sooc_status st = sooc_sensor_open(&s, "libcamera", &p);
    double dt = sooc_seconds() - t0;
    if (st == SOOC_OK) {
        sooc_sensor_info info;
        sooc_sensor_get_info(s, &info);
        printf("SKIP: a camera is present (%s); the zero-camera path cannot be tested here\n", info.device);
        sooc_sensor_close(s);
        return SOOC_TEST_SKIP;
    }
    CHECK_MSG(st == SOOC_ENOTFOUND, "open: %s %s", sooc_status_str(st), sooc_errmsg());
    CHECK_MSG(strstr(sooc_errmsg(), "no cameras") != NULL, "message: %s", sooc_errmsg());
    CHECK(s == NULL);
    printf("  libcamera with no camera: \"%s\" after %.0f ms\n", sooc_errmsg(), dt * 1e3);
    /* twice: the shared CameraManager is released and restarted cleanly */
    CHECK(sooc_sensor_open(&s, "libcamera", &p) == SOOC_ENOTFOUND);
    return check_report("test_libcamera");
}
