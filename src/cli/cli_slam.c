/* `sooc3d render --map` over a map made by a camera without a pose source:
 * the cameras go where the map's tracking keyframes put them
 * (include/sooc3d/cogmap.h, docs/slam.md). */
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "sooc3d/core.h"
#include "sooc3d/cogmap.h"

typedef struct kfpose {
    int64_t frame;   /* t_ns */
    int32_t run;
    double T[16];
} kfpose;

typedef struct kf_list {
    kfpose *v;
    size_t n, cap;
    sooc_status st;
} kf_list;

static int collect(const sooc_slamdb_kf *k, void *user) {
    kf_list *L = user;
    if (L->n == L->cap) {
        size_t nc = L->cap ? 2 * L->cap : 64;
        kfpose *v = realloc(L->v, nc * sizeof *v);
        if (!v) {
            L->st = SOOC_ENOMEM;
            return 1;
        }
        L->v = v;
        L->cap = nc;
    }
    kfpose *p = &L->v[L->n++];
    p->frame = k->t_ns;   /* frames are matched by timestamp: numbering differs between readers */
    p->run = k->run;
    memcpy(p->T, k->T_wc, sizeof p->T);
    return 0;
}

/* by time, the latest run first */
static int cmp_kf(const void *a, const void *b) {
    const kfpose *x = a, *y = b;
    if (x->frame != y->frame) return x->frame < y->frame ? -1 : 1;
    return (x->run < y->run) - (x->run > y->run);
}

sooc_status sooc_cli_slam_poses(const char *db, const double T_world_src[16], sooc_frame *fr, int n, int *moved,
                                int64_t *n_kf) {
    *moved = 0;
    *n_kf = 0;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.readonly = 1;
    sooc_mapstore *ms = NULL;
    sooc_status st = sooc_mapstore_open(&ms, db, &mp);
    if (st) return st;
    kf_list L = {NULL, 0, 0, SOOC_OK};
    st = sooc_mapstore_slam_foreach_keyframe(ms, collect, &L);
    sooc_mapstore_close(ms);
    if (!st) st = L.st;
    if (st || L.n == 0) {
        free(L.v);
        return st;
    }
    qsort(L.v, L.n, sizeof *L.v, cmp_kf);
    size_t k = 0;
    for (size_t i = 0; i < L.n; i++)   /* one keyframe per timestamp: the latest run's */
        if (!k || L.v[k - 1].frame != L.v[i].frame) L.v[k++] = L.v[i];
    *n_kf = (int64_t)k;
    for (int i = 0; i < n; i++) {
        int64_t f = fr[i].t_ns;
        size_t hi = 0;
        while (hi < k && L.v[hi].frame < f) hi++;
        double T[16];
        if (hi < k && L.v[hi].frame == f) memcpy(T, L.v[hi].T, sizeof T);
        else if (hi == 0) memcpy(T, L.v[0].T, sizeof T);
        else if (hi == k) memcpy(T, L.v[k - 1].T, sizeof T);
        else {   /* between two keyframes: interpolated in time */
            const kfpose *a = &L.v[hi - 1], *b = &L.v[hi];
            sooc_se3_interp(T, a->T, b->T, (double)(f - a->frame) / (double)(b->frame - a->frame));
        }
        sooc_se3_mul(fr[i].T_wc, T_world_src, T);
        (*moved)++;
    }
    free(L.v);
    return SOOC_OK;
}
