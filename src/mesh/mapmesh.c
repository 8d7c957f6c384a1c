/* Meshes of a map (include/sooc3d/render.h, docs/mesh.md): each entry's own
 * component of the model's field (model.h sooc_model_field_*, which picks up
 * a finetuned decoder kept with the map), sampled over its locality box in
 * its own frame; the layout over each layout block. The field is built for a
 * virtual camera that sees the entry (or whose active block is the block),
 * so the map is meshed with exactly the field that `render` and `eval` use. */
#include "sooc3d/render.h"
#include "sooc3d/core.h"
#include "sooc3d/model.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void sooc_mesh_opts_default(sooc_mesh_opts *o) {
    memset(o, 0, sizeof *o);
    o->res = SOOC_MESH_RES_DEFAULT;
    o->level = SOOC_MESH_LEVEL;
    o->threads = 0;
    o->layout_cell = 0.05;
    o->layout_y[0] = -0.25;
    o->layout_y[1] = 3.0;
}

/* A level camera at (x, h, z) looking along the world heading psi
 * (forward = (sin psi, 0, cos psi)); OpenCV axes (x right, y down, z ahead). */
static void camera_at(double T_wc[16], double x, double h, double z, double psi) {
    double f[3] = {sin(psi), 0, cos(psi)}, d[3] = {0, -1, 0}, r[3] = {-f[2], 0, f[0]};
    sooc_se3_identity(T_wc);
    for (int i = 0; i < 3; i++) T_wc[4 * i] = r[i], T_wc[4 * i + 1] = d[i], T_wc[4 * i + 2] = f[i];
    T_wc[3] = x, T_wc[7] = h, T_wc[11] = z;
}

static void intrinsics_90(sooc_intrinsics *K) {
    memset(K, 0, sizeof *K);
    K->width = K->height = 64;
    K->fx = K->fy = 32;
    K->cx = K->cy = 32;
    K->dist_model = SOOC_DIST_NONE;
}

/* T_wg of a field: T_wc * inverse(T_gc). */
static void field_T_wg(const sooc_model_field *F, const double T_wc[16], double T_wg[16]) {
    double T_gc[16], T_cg[16];
    sooc_model_field_T_fc(F, T_gc);
    sooc_se3_inverse(T_cg, T_gc);
    sooc_se3_mul(T_wg, T_wc, T_cg);
}

static void grid_res(sooc_mesh_grid *g, int res) {
    double ext[3], mx = 0;
    for (int d = 0; d < 3; d++) {
        ext[d] = g->hi[d] - g->lo[d];
        if (ext[d] > mx) mx = ext[d];
    }
    for (int d = 0; d < 3; d++) {   /* cubic voxels: res samples along the longest side */
        int r = (int)lround(ext[d] / mx * (res - 1)) + 1;
        g->res[d] = r < 2 ? 2 : r;
    }
}

sooc_status sooc_mesh_object(struct sooc_model *m, const sooc_cogmap *map, uint64_t id, const sooc_mesh_opts *o,
                             sooc_mesh *out) {
    sooc_mesh_opts od;
    if (!o) sooc_mesh_opts_default(&od), o = &od;
    out->n_vert = out->n_tri = 0;
    if (o->res < 2 || o->res > 1024) return sooc_seterr(SOOC_EINVAL, "mesh: --res %d is outside 2..1024", o->res);
    sooc_cogmap_entry e;
    sooc_status st = sooc_cogmap_get(map, id, &e);
    if (st) return st;
    const sooc_model_config *c = sooc_model_get_config(m);
    double u = c->unit_m, Rh = c->box_rh * u, Hb = c->box_hb * u;
    double D = 4 * Rh + c->t_near * u;   /* the whole box in a 90-degree view, well inside d_clip */
    sooc_intrinsics K;
    intrinsics_90(&K);
    /* look at the entry from four sides until its component is in the field
     * (the field keeps the top 63 in-view entries by presence) */
    for (int side = 0; side < 4; side++) {
        double psi = e.Theta + side * (M_PI / 2), T_wc[16];
        camera_at(T_wc, e.X - D * sin(psi), 0.5 * Hb, e.Z - D * cos(psi), psi);
        sooc_model_field *F = NULL;
        if ((st = sooc_model_field_create(&F, m, map, T_wc, &K, SOOC_RENDER_MAX_COMP - 1, NULL))) return st;
        const sooc_field *f = sooc_model_field_get(F);
        int comp = -1;
        for (int k = 1; k < f->n_comp; k++)
            if (sooc_model_field_comp_id(F, k) == id) comp = k;
        if (comp < 0 || !f->boxes || !f->boxes[comp].enabled) {
            sooc_model_field_destroy(F);
            continue;
        }
        const sooc_render_box *b = &f->boxes[comp];
        sooc_mesh_grid g;
        memset(&g, 0, sizeof g);
        double T_wg[16];
        field_T_wg(F, T_wc, T_wg);
        memcpy(g.T_eg, b->T_fb, sizeof g.T_eg);
        sooc_se3_mul(g.T_og, T_wg, b->T_fb);
        for (int d = 0; d < 3; d++) g.lo[d] = b->lo[d], g.hi[d] = b->hi[d];
        grid_res(&g, o->res);
        st = sooc_mesh_extract(f, comp, &g, o->level, o->threads, out);
        sooc_model_field_destroy(F);
        if (st) return sooc_adderr(st, "mesh of map entry %llu", (unsigned long long)id);
        return SOOC_OK;
    }
    return sooc_seterr(SOOC_ENOTFOUND, "mesh: map entry %llu is not in the field of any camera looking at it",
                       (unsigned long long)id);
}

typedef struct blocks {
    int32_t *ij;
    size_t n, cap;
    int oom;
} blocks;

static int collect_block(void *user, int32_t bi, int32_t bj, const float *mu, const float *lv) {
    (void)mu, (void)lv;
    blocks *B = user;
    if (B->n == B->cap) {
        size_t cap = B->cap ? 2 * B->cap : 16;
        int32_t *p = sooc_realloc(B->ij, cap * 2 * sizeof(int32_t));
        if (!p) return B->oom = 1;
        B->ij = p, B->cap = cap;
    }
    B->ij[2 * B->n] = bi, B->ij[2 * B->n + 1] = bj;
    B->n++;
    return 0;
}

static int cmp_block(const void *a, const void *b) {
    const int32_t *x = a, *y = b;
    if (x[0] != y[0]) return x[0] < y[0] ? -1 : 1;
    return x[1] < y[1] ? -1 : x[1] > y[1];
}

sooc_status sooc_mesh_layout(struct sooc_model *m, const sooc_cogmap *map, const sooc_mesh_opts *o,
                             sooc_mesh *out) {
    sooc_mesh_opts od;
    if (!o) sooc_mesh_opts_default(&od), o = &od;
    out->n_vert = out->n_tri = 0;
    const sooc_model_config *c = sooc_model_get_config(m);
    double u = c->unit_m, bs = c->block_size * u, dclip = c->d_clip * u;
    if (!(o->layout_cell > 0) || !(o->layout_y[1] > o->layout_y[0]))
        return sooc_seterr(SOOC_EINVAL, "mesh: bad layout grid (cell %g m, y %g..%g)", o->layout_cell, o->layout_y[0],
                           o->layout_y[1]);
    blocks B = {0};
    sooc_cogmap_layout_foreach(map, collect_block, &B);
    if (B.oom) {
        sooc_free(B.ij);
        return SOOC_ENOMEM;
    }
    if (!B.n) {   /* no layout latent yet: the prior, over the block at the origin */
        int32_t bi, bj;
        sooc_cogmap_block_of(map, 0, 0, &bi, &bj);
        collect_block(&B, bi, bj, NULL, NULL);
        if (B.oom) return SOOC_ENOMEM;
    }
    qsort(B.ij, B.n, 2 * sizeof(int32_t), cmp_block);   /* a deterministic order */
    sooc_intrinsics K;
    intrinsics_90(&K);
    sooc_mesh part = {0};
    sooc_status st = SOOC_OK;
    for (size_t i = 0; i < B.n && !st; i++) {
        int32_t bi = B.ij[2 * i], bj = B.ij[2 * i + 1], ai, aj;
        double X, Z, T_wc[16];
        sooc_cogmap_block_origin(map, bi, bj, &X, &Z);
        /* the active block of a view holds the ground point d_clip / 2 ahead */
        camera_at(T_wc, X, 1.0 * u, Z - 0.5 * dclip, 0);
        if ((st = sooc_cogmap_active_block(map, T_wc, dclip, &ai, &aj, NULL))) break;
        if (ai != bi || aj != bj) {
            st = sooc_seterr(SOOC_ERR, "mesh: a camera for layout block (%d, %d) sees block (%d, %d)", (int)bi,
                             (int)bj, (int)ai, (int)aj);
            break;
        }
        sooc_model_field *F = NULL;
        if ((st = sooc_model_field_create(&F, m, map, T_wc, &K, 0, NULL))) break;
        sooc_mesh_grid g;
        memset(&g, 0, sizeof g);
        double T_wg[16];
        field_T_wg(F, T_wc, T_wg);
        sooc_se3_inverse(g.T_eg, T_wg);   /* grid in world coordinates */
        sooc_se3_identity(g.T_og);
        g.lo[0] = X - 0.5 * bs, g.hi[0] = X + 0.5 * bs;
        g.lo[1] = o->layout_y[0] * u, g.hi[1] = o->layout_y[1] * u;
        g.lo[2] = Z - 0.5 * bs, g.hi[2] = Z + 0.5 * bs;
        for (int d = 0; d < 3; d++) {
            int r = (int)ceil((g.hi[d] - g.lo[d]) / (o->layout_cell * u)) + 1;
            g.res[d] = r < 2 ? 2 : r > 1024 ? 1024 : r;
        }
        st = sooc_mesh_extract(sooc_model_field_get(F), 0, &g, o->level, o->threads, &part);
        sooc_model_field_destroy(F);
        if (!st) st = sooc_mesh_append(out, &part);
        if (st) sooc_adderr(st, "mesh of layout block (%d, %d)", (int)bi, (int)bj);
    }
    sooc_mesh_free(&part);
    sooc_free(B.ij);
    if (st) out->n_vert = out->n_tri = 0;
    return st;
}

sooc_status sooc_mesh_write_map(struct sooc_model *m, const sooc_cogmap *map, const char *dir, const sooc_mesh_opts *o,
                                const uint64_t *ids, size_t n_ids, sooc_mesh_write_stats *stats) {
    sooc_mesh_opts od;
    if (!o) sooc_mesh_opts_default(&od), o = &od;
    sooc_mesh_write_stats S;
    memset(&S, 0, sizeof S);
    sooc_status st = sooc_mkdirs(dir);
    if (st) return sooc_adderr(st, "creating %s", dir);
    size_t ne = 0;
    sooc_cogmap_entry *E = NULL;
    if (!ids) {
        if ((st = sooc_cogmap_entries(map, NULL, 0, &ne))) return st;
        E = sooc_malloc((ne ? ne : 1) * sizeof *E);
        if (!E) return SOOC_ENOMEM;
        if ((st = sooc_cogmap_entries(map, E, ne, &ne))) {
            sooc_free(E);
            return st;
        }
    } else {
        ne = n_ids;
    }
    sooc_mesh obj = {0}, scene = {0};
    char path[4096], name[64], com[160];
    for (size_t i = 0; i < ne && !st; i++) {
        uint64_t id = ids ? ids[i] : E[i].id;
        if ((st = sooc_mesh_object(m, map, id, o, &obj))) break;
        snprintf(name, sizeof name, "object_%llu.ply", (unsigned long long)id);
        snprintf(com, sizeof com, "sooc3d mesh: map entry %llu, world frame (m, +y up, floor y = 0), level %g",
                 (unsigned long long)id, (double)o->level);
        if ((st = sooc_path_join(path, sizeof path, dir, name))) break;
        if ((st = sooc_mesh_write_ply(&obj, path, com))) break;
        if ((st = sooc_mesh_append(&scene, &obj))) break;
        S.n_objects++;
        S.n_empty += obj.n_tri == 0;
    }
    if (!st) st = sooc_mesh_layout(m, map, o, &obj);
    if (!st) {
        S.n_layout_tri = obj.n_tri;
        st = sooc_mesh_append(&scene, &obj);
    }
    if (!st) st = sooc_path_join(path, sizeof path, dir, "scene.ply");
    if (!st) {
        snprintf(com, sizeof com, "sooc3d mesh: %d objects + layout, world frame (m, +y up, floor y = 0), level %g",
                 S.n_objects, (double)o->level);
        st = sooc_mesh_write_ply(&scene, path, com);
    }
    S.n_vert = scene.n_vert, S.n_tri = scene.n_tri;
    sooc_mesh_free(&obj);
    sooc_mesh_free(&scene);
    sooc_free(E);
    if (stats) *stats = S;
    return st;
}
