/* The map's world frame in the store (sooc_mapstore_frame_put/get): exact
 * round trip across a reopen, absent frame reported as not found, invalid
 * frames refused, malformed stored text gives an error naming the file. */
#include "check.h"
#include "sooc3d/cogmap.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static sooc_status open_store(sooc_mapstore **s, const char *path) {
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.dim = 4;
    p.layout_dim = 0;
    return sooc_mapstore_open(s, path, &p);
}

int main(void) {
    char dir[] = "/tmp/sooc_msframe_XXXXXX";
    if (!mkdtemp(dir)) return 1;
    char path[300];
    snprintf(path, sizeof path, "%s/map.sqlite", dir);

    sooc_mapstore *s = NULL;
    CHECK_OK(open_store(&s, path));
    if (!s) return check_report("test_mapstore_frame");
    sooc_map_frame f, g;
    int found = -1;
    memset(&g, 0, sizeof g);
    CHECK_OK(sooc_mapstore_frame_get(s, &g, &found));
    CHECK(found == 0);

    /* rotation about x by 0.3 rad then a shift: a rigid transform with awkward values */
    memset(&f, 0, sizeof f);
    double c = cos(0.3), sn = sin(0.3);
    double T[16] = {1, 0, 0, 0.1, 0, c, -sn, 1.0 / 3.0, 0, sn, c, -2.5e-7, 0, 0, 0, 1};
    memcpy(f.T_world_src, T, sizeof T);
    f.up_src[0] = 0; f.up_src[1] = c; f.up_src[2] = -sn;
    f.plane_src[0] = 0; f.plane_src[1] = c; f.plane_src[2] = -sn; f.plane_src[3] = 1.0 / 7.0;
    f.cam_height_m = 1.4142135623730951;
    f.up_source = 2;
    CHECK_OK(sooc_mapstore_frame_put(s, &f));
    sooc_mapstore_close(s);

    s = NULL;
    CHECK_OK(open_store(&s, path));
    found = 0;
    CHECK_OK(sooc_mapstore_frame_get(s, &g, &found));
    CHECK(found == 1);
    CHECK(!memcmp(g.T_world_src, f.T_world_src, sizeof f.T_world_src));
    CHECK(!memcmp(g.up_src, f.up_src, sizeof f.up_src));
    CHECK(!memcmp(g.plane_src, f.plane_src, sizeof f.plane_src));
    CHECK(g.cam_height_m == f.cam_height_m);
    CHECK(g.up_source == 2);

    /* invalid frames are refused and leave the stored one alone */
    sooc_map_frame b = f;
    b.T_world_src[0] = 2;   /* not rigid */
    CHECK(sooc_mapstore_frame_put(s, &b) == SOOC_EINVAL);
    CHECK(strstr(sooc_errmsg(), path) != NULL);
    b = f;
    b.cam_height_m = NAN;
    CHECK(sooc_mapstore_frame_put(s, &b) == SOOC_EINVAL);
    b = f;
    b.up_source = 5;
    CHECK(sooc_mapstore_frame_put(s, &b) == SOOC_EINVAL);
    CHECK_OK(sooc_mapstore_frame_get(s, &g, &found));
    CHECK(found == 1 && g.up_source == 2);

    /* a malformed stored value */
    CHECK_OK(sooc_mapstore_meta_set(s, "world_frame", "v1 0 1 2 3"));
    found = 7;
    sooc_status st = sooc_mapstore_frame_get(s, &g, &found);
    CHECK(st == SOOC_EFORMAT);
    CHECK(found == 0);
    CHECK_MSG(strstr(sooc_errmsg(), path) != NULL, "%s", sooc_errmsg());
    /* well formed numbers but not a rigid transform */
    char bad[1024];
    int k = snprintf(bad, sizeof bad, "v1 0");
    for (int i = 0; i < 24; i++) k += snprintf(bad + k, sizeof bad - (size_t)k, " 3");
    CHECK_OK(sooc_mapstore_meta_set(s, "world_frame", bad));
    CHECK(sooc_mapstore_frame_get(s, &g, &found) == SOOC_EFORMAT);
    CHECK_MSG(strstr(sooc_errmsg(), "rigid") != NULL, "%s", sooc_errmsg());
    sooc_mapstore_close(s);

    unlink(path);
    char w[320];
    snprintf(w, sizeof w, "%s-wal", path);
    unlink(w);
    snprintf(w, sizeof w, "%s-shm", path);
    unlink(w);
    rmdir(dir);
    return check_report("test_mapstore_frame");
}
