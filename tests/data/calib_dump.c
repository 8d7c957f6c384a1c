/* calib_dump: print what sooc_calib_load (our libyaml loader) read from each
 * calibration file, one JSON object per file on its own line, with every
 * double at %.17g (exact round trip). Used by test_calib_readers.py, which
 * compares it with PyYAML and OpenCV FileStorage.
 *   calib_dump <file.yaml>...   exit 1 (message on stderr) if a file fails */
#include "sooc3d/frame.h"

#include <stdio.h>

static void arr(const char *key, const double *v, int n) {
    printf(", \"%s\": [", key);
    for (int i = 0; i < n; i++) printf("%s%.17g", i ? ", " : "", v[i]);
    printf("]");
}

int main(int argc, char **argv) {
    static const char *models[] = {"none", "plumb_bob", "rational_polynomial", "equidistant"};
    for (int a = 1; a < argc; a++) {
        sooc_calib c;
        sooc_status s = sooc_calib_load(argv[a], &c);
        if (s != SOOC_OK) {
            fprintf(stderr, "calib_dump: %s\n", sooc_errmsg());
            return 1;
        }
        const sooc_intrinsics *K = &c.K;
        double Km[9] = {K->fx, 0, K->cx, 0, K->fy, K->cy, 0, 0, 1};
        int dm = (int)K->dist_model;
        printf("{\"file\": \"%s\", \"camera_name\": \"%s\", \"image_width\": %d, \"image_height\": %d",
               argv[a], c.camera_name, K->width, K->height);
        arr("camera_matrix", Km, 9);
        printf(", \"distortion_model\": \"%s\"", dm >= 0 && dm <= 3 ? models[dm] : "?");
        arr("distortion_coefficients", K->dist, c.n_dist);
        arr("rectification_matrix", c.R_rect, 9);
        arr("projection_matrix", c.P, 12);
        printf(", \"depth_scale\": %.17g", c.depth_scale);
        printf(", \"depth_registered\": %s", c.depth_registered < 0 ? "null"
                                             : c.depth_registered ? "true" : "false");
        if (c.depth_shift >= 0) printf(", \"depth_shift\": %d", c.depth_shift);
        if (c.depth_invalid >= 0) printf(", \"depth_invalid\": %d", c.depth_invalid);
        if (c.has_T_color_depth) arr("T_color_depth", c.T_color_depth, 16);
        if (c.has_T_effector_camera) {
            arr("T_effector_camera", c.T_effector_camera, 16);
            printf(", \"T_effector_camera.parent\": \"%s\", \"T_effector_camera.child\": \"%s\"",
                   c.effector_parent, c.effector_child);
        }
        printf("}\n");
    }
    return 0;
}
