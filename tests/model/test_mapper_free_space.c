/* The free-space evidence of the node's revisit rules (sooc_mapper_free_space,
 * docs/cogmap.md "Revisits"), on crafted depth: a 64x64 camera 1.5 m above the
 * floor looking along +z, tilted 30 degrees down, depth rendered exactly (floor
 * plane y = 0 and an optional axis-aligned box on it). */
#include "check.h"
#include "sooc3d/mapper.h"

#include <math.h>
#include <string.h>

#define W 64
#define H 64

typedef struct box {
    int on;
    double x0, x1, y1, z0, z1;   /* [x0, x1] x [0, y1] x [z0, z1] */
} box;

static void camera(sooc_cogmap_camera *cam) {
    memset(cam, 0, sizeof *cam);
    double t = 30.0 * M_PI / 180.0, c = cos(t), s = sin(t);
    /* camera axes in the world (OpenCV: x right, y down, z forward) */
    double xc[3] = {-1, 0, 0}, yc[3] = {0, -c, -s}, zc[3] = {0, -s, c}, p[3] = {0, 1.5, 0};
    for (int r = 0; r < 3; r++) {
        cam->T_wc[4 * r + 0] = xc[r];
        cam->T_wc[4 * r + 1] = yc[r];
        cam->T_wc[4 * r + 2] = zc[r];
        cam->T_wc[4 * r + 3] = p[r];
    }
    cam->T_wc[15] = 1;
    cam->K.width = W;
    cam->K.height = H;
    cam->K.fx = cam->K.fy = 55;
    cam->K.cx = cam->K.cy = 32;
    cam->t_near = 0.1;
    cam->d_clip = 8;
    cam->R_h = 0.6;
    cam->H_b = 1.2;
    cam->mode = SOOC_INVIEW_CENTRE;
}

/* planar depth of every pixel centre: floor, or the box where it is nearer */
static void render(const sooc_cogmap_camera *cam, const box *b, float *depth, uint8_t *valid) {
    const double *T = cam->T_wc;
    for (int v = 0; v < H; v++)
        for (int u = 0; u < W; u++) {
            double dc[3] = {(u + 0.5 - cam->K.cx) / cam->K.fx, (v + 0.5 - cam->K.cy) / cam->K.fy, 1};
            double o[3] = {T[3], T[7], T[11]}, d[3];
            for (int r = 0; r < 3; r++) d[r] = T[4 * r] * dc[0] + T[4 * r + 1] * dc[1] + T[4 * r + 2] * dc[2];
            double t = d[1] < 0 ? -o[1] / d[1] : INFINITY;   /* planar depth (dc has z = 1) */
            if (b && b->on) {   /* slab test */
                double lo[3] = {b->x0, 0, b->z0}, hi[3] = {b->x1, b->y1, b->z1}, tn = 0, tx = INFINITY;
                for (int a = 0; a < 3; a++) {
                    if (fabs(d[a]) < 1e-12) {
                        if (o[a] < lo[a] || o[a] > hi[a]) tn = INFINITY;
                        continue;
                    }
                    double t0 = (lo[a] - o[a]) / d[a], t1 = (hi[a] - o[a]) / d[a];
                    if (t0 > t1) {
                        double x = t0;
                        t0 = t1;
                        t1 = x;
                    }
                    if (t0 > tn) tn = t0;
                    if (t1 < tx) tx = t1;
                }
                if (tn <= tx && tn < t) t = tn;
            }
            int ok = isfinite(t) && t < 20;
            depth[v * W + u] = ok ? (float)t : 0.0f;
            valid[v * W + u] = (uint8_t)ok;
        }
}

int main(void) {
    static float depth[W * H];
    static uint8_t valid[W * H];
    sooc_cogmap_camera cam;
    camera(&cam);
    sooc_frame f;
    memset(&f, 0, sizeof f);
    f.width = W;
    f.height = H;
    f.depth = depth;
    f.valid = valid;
    f.has_pose = 1;
    memcpy(f.T_wc, cam.T_wc, sizeof f.T_wc);
    f.K = cam.K;

    /* empty floor: an entry 3 m ahead claims an object where the rays reach the floor behind it */
    render(&cam, NULL, depth, valid);
    CHECK(sooc_mapper_free_space(&cam, &f, 0.0, 3.0) == 1);
    CHECK(sooc_mapper_free_space(&cam, &f, 0.5, 4.5) == 1);
    /* behind the camera / outside the image: no evidence */
    CHECK(sooc_mapper_free_space(&cam, &f, 0.0, -3.0) == -1);
    CHECK(sooc_mapper_free_space(&cam, &f, 9.0, 3.0) == -1);

    /* a 0.6 m box, 0.8 m tall, centred 3 m ahead */
    box b = {1, -0.3, 0.3, 0.8, 2.7, 3.3};
    render(&cam, &b, depth, valid);
    CHECK(sooc_mapper_free_space(&cam, &f, 0.0, 3.0) == 0);      /* on the object */
    CHECK(sooc_mapper_free_space(&cam, &f, 0.15, 2.9) == 0);     /* offset inside its footprint */
    CHECK(sooc_mapper_free_space(&cam, &f, 0.0, 3.7) == -1);     /* right behind it: hidden, no evidence */
    CHECK(sooc_mapper_free_space(&cam, &f, 0.8, 3.0) == 1);      /* a duplicate 0.8 m beside it: free */
    CHECK(sooc_mapper_free_space(&cam, &f, -1.0, 3.0) == 1);

    /* invalid depth is no evidence */
    memset(valid, 0, sizeof valid);
    CHECK(sooc_mapper_free_space(&cam, &f, 0.8, 3.0) == -1);
    f.valid = NULL;   /* depth 0 = invalid without a valid mask */
    memset(depth, 0, sizeof depth);
    CHECK(sooc_mapper_free_space(&cam, &f, 0.8, 3.0) == -1);

    printf("%d checks, %d failed\n", g_check_n, g_check_fail);
    return g_check_fail ? 1 : 0;
}
