/* Generator benchmark: rendered frames per second (render only, no PNG) at
 * 64x64 and 640x480, both presets, scale l (a busy walk-through view), plus
 * the full `sooc3d gen` pipeline rate (render + PNG + files) at 64x64.
 * Usage: bench_gen [reps]. Last line: JSON. */
#include "sooc3d/gen.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static double fps_render(sooc_gen_preset preset, int w, int h, int min_frames, double min_s, uint32_t *crc) {
    sooc_gen_params p;
    sooc_gen_params_default(&p);
    p.preset = preset;
    p.scale = SOOC_GEN_L;
    p.width = w;
    p.height = h;
    p.seed = 5;
    sooc_scene sc;
    sooc_scene_init(&sc);
    if (sooc_gen_scene(&sc, &p, 0)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, w, h, p.fov_deg);
    sooc_frame f = {0};
    sooc_gen_render_view(&sc, sc.view_T_wc, &K, &f); /* warm-up */
    double t0 = sooc_seconds();
    int n = 0;
    *crc = 0;
    while (n < min_frames || sooc_seconds() - t0 < min_s) {
        int v = n % sc.n_views;
        if (sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, &f)) { fprintf(stderr, "%s\n", sooc_errmsg()); exit(1); }
        if (n < 3) *crc = sooc_crc32(*crc, f.depth, sizeof(float) * (size_t)w * h);
        n++;
    }
    double fps = n / (sooc_seconds() - t0);
    sooc_frame_free(&f);
    sooc_scene_free(&sc);
    return fps;
}

int main(int argc, char **argv) {
    double min_s = argc > 1 ? atof(argv[1]) : 2.0;
    uint32_t c1, c2, c3, c4;
    double u64 = fps_render(SOOC_GEN_UNITY, 64, 64, 100, min_s, &c1);
    double b64 = fps_render(SOOC_GEN_BLENDER, 64, 64, 100, min_s, &c2);
    double u640 = fps_render(SOOC_GEN_UNITY, 640, 480, 3, min_s, &c3);
    double b640 = fps_render(SOOC_GEN_BLENDER, 640, 480, 3, min_s, &c4);
    printf("render only (scale l, OpenMP over rows for large frames):\n");
    printf("  unity   64x64   %8.1f fps  (depth crc %08x)\n", u64, c1);
    printf("  blender 64x64   %8.1f fps  (depth crc %08x)\n", b64, c2);
    printf("  unity   640x480 %8.2f fps  (depth crc %08x)\n", u640, c3);
    printf("  blender 640x480 %8.2f fps  (depth crc %08x)\n", b640, c4);
    /* full pipeline into a temp dir */
    char dir[] = "/tmp/sooc_bench_gen_XXXXXX";
    double pipe = 0;
    if (mkdtemp(dir)) {
        sooc_gen_params p;
        sooc_gen_params_default(&p);
        p.scale = SOOC_GEN_M;
        p.n_scenes = 4;
        double t0 = sooc_seconds();
        if (sooc_gen_run(&p, dir, NULL, NULL, NULL)) fprintf(stderr, "%s\n", sooc_errmsg());
        pipe = 4.0 * 24 / (sooc_seconds() - t0);
        char cmd[200];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd)) {}
        printf("  full pipeline unity m 64x64 (render + PNG + meshes): %.1f views/s\n", pipe);
    }
    printf("{\"fps_64\": %.1f, \"fps_640x480\": %.2f, \"fps_64_blender\": %.1f, \"fps_640x480_blender\": %.2f, "
           "\"pipeline_views_per_s_64\": %.1f}\n", u64, u640, b64, b640, pipe);
    return 0;
}
