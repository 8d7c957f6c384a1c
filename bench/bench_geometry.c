/* bench_geometry: object geometry for planners on generated
 * scenes. Maps every scene of a `sooc3d gen` dataset with a model (input
 * views, the mapper's default geometry budget), then computes every stale
 * tight box and scores the final map against the scene's ground truth
 * (eval_geom.h): median extent error, height error, the fraction of per-axis
 * position errors within one sigma, symmetry-flag agreement; and the cost:
 * mapper update time with and without the geometry budget, time per box.
 *
 *   bench_geometry MODEL DATA_DIR [--scenes N] [--csv OUT] [--budget B]
 *
 * --csv writes one row per matched object (for fitting the spread
 * constants in mapper.h). Last line: a JSON object. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "sooc3d/eval.h"
#include "eval/eval_geom.h"
#include "sooc3d/model.h"
#include "sooc3d/mapper.h"
#include "sooc3d/gen.h"
#include "sooc3d/train.h"

static int cmp_d(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n) {
    if (n <= 0) return NAN;
    qsort(v, (size_t)n, sizeof *v, cmp_d);
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/* mapper over the scene's input views; returns the summed update seconds */
static sooc_status map_scene(sooc_model *m, const sooc_dataset *ds, int s, int budget, sooc_mapper **out,
                             double *upd_s, int *n_upd) {
    sooc_model *copy = NULL;
    sooc_status st = sooc_eval_model_copy(m, &copy);
    if (st) return st;
    if ((st = sooc_mapper_create_with_model(out, copy, 0, 1, 0))) {
        sooc_model_destroy(copy);
        return st;
    }
    sooc_mapper_set_geometry_budget(*out, budget);
    int nv = sooc_dataset_n_views(ds, s);
    for (int v = 0; v < nv; v++) {
        const sooc_frame *f = sooc_dataset_view(ds, s, v);
        if (f->is_query) continue;
        double t0 = sooc_seconds();
        if ((st = sooc_mapper_update(*out, f, NULL))) return st;
        *upd_s += sooc_seconds() - t0;
        (*n_upd)++;
    }
    return SOOC_OK;
}

int main(int argc, char **argv) {
    if (argc < 3) {
        fprintf(stderr, "usage: bench_geometry MODEL DATA_DIR [--scenes N] [--csv OUT] [--budget B]\n");
        return 2;
    }
    const char *model = argv[1], *dir = argv[2], *csv = NULL;
    int max_scenes = 1000, budget = SOOC_OBJGEOM_BUDGET, sweep = 0;
    enum { NL = 5, NR = 4 };
    static const float levels[NL] = {0.1f, 0.2f, 0.3f, 0.5f, 0.7f};
    static const int ress[NR] = {8, 12, 16, 24};
    double *sw[NL][NR] = {{0}};
    int n_sw = 0;
    for (int i = 3; i < argc; i++) {
        if (!strcmp(argv[i], "--scenes") && i + 1 < argc) max_scenes = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--csv") && i + 1 < argc) csv = argv[++i];
        else if (!strcmp(argv[i], "--budget") && i + 1 < argc) budget = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--sweep")) sweep = 1;
        else {
            fprintf(stderr, "bench_geometry: unknown option %s\n", argv[i]);
            return 2;
        }
    }
    sooc_model *m = NULL;
    sooc_dataset *ds = NULL;
    FILE *fc = NULL;
    sooc_map_entry *ent = NULL;
    sooc_geom_match *mt = NULL;
    double *ext = NULL, *hgt = NULL;
    int n_ext = 0, cap_ext = 0;
    long n_ax = 0, n_in = 0, n_sym = 0, n_sym_ok = 0, n_match = 0, n_gt = 0;
    double upd_geo = 0, upd_none = 0, box_s = 0, one_s = 0;
    long one_ev = 0, n_one = 0;
    int n_upd_geo = 0, n_upd_none = 0, n_boxes = 0;
    sooc_status st = sooc_model_load(&m, model, NULL, NULL);
    if (st) goto fail;
    const sooc_model_config *c = sooc_model_get_config(m);
    if ((st = sooc_dataset_open(&ds, &dir, 1, c->img_w, c->img_h))) goto fail;
    if (csv && !(fc = fopen(csv, "w"))) {
        st = sooc_seterr(SOOC_EIO, "%s: cannot write", csv);
        goto fail;
    }
    if (fc)
        fprintf(fc, "scene,gt_id,shape,dist_m,ext_err_cm,height_err_cm,ext_pred_x,ext_pred_y,ext_pred_z,ext_gt_x,"
                    "ext_gt_y,ext_gt_z,err_x,err_z,sig_x,sig_z,rho_t,reg_n,reg_vx,reg_vz,obs,sym_pred,sym_gt,sym_iou,cerr_x,cerr_z\n");
    int ns = sooc_dataset_n_scenes(ds);
    if (ns > max_scenes) ns = max_scenes;
    for (int s = 0; s < ns; s++) {
        char path[1024];
        sooc_scene sc;
        sooc_scene_init(&sc);
        if ((st = sooc_path_join(path, sizeof path, sooc_dataset_scene_path(ds, s), "scene.yaml")) ||
            (st = sooc_scene_load(path, &sc)))
            goto fail;
        sooc_mapper *mp = NULL, *mp0 = NULL;
        st = map_scene(m, ds, s, 0, &mp0, &upd_none, &n_upd_none);   /* the same updates without geometry */
        sooc_mapper_destroy(mp0);
        if (!st) st = map_scene(m, ds, s, budget, &mp, &upd_geo, &n_upd_geo);
        int nd = 0;
        double t0 = sooc_seconds();
        if (!st) st = sooc_mapper_refresh_geometry(mp, -1, &nd);
        box_s += sooc_seconds() - t0;
        n_boxes += nd;
        size_t n = 0;
        if (!st) st = sooc_mapper_entries(mp, NULL, 0, &n);
        sooc_free(ent);
        ent = sooc_calloc(n + 1, sizeof *ent);
        sooc_free(mt);
        mt = sooc_calloc((size_t)sc.n_objects + 1, sizeof *mt);
        if (!st && (!ent || !mt)) st = SOOC_ENOMEM;
        if (!st) st = sooc_mapper_entries(mp, ent, n, &n);
        int nm = 0;
        if (!st) st = sooc_geom_eval_scene(ent, n, &sc, 0.5, mt, &nm);
        for (size_t i = 0; !st && i < n && i < 8; i++) {   /* cost of one box: time and field evaluations */
            sooc_objgeom_opts o;
            sooc_objgeom_opts_default(&o);
            sooc_objgeom_box bx;
            double t1 = sooc_seconds();
            st = sooc_objgeom_entry_box(sooc_mapper_model(mp), sooc_mapper_cogmap(mp), ent[i].id, &o, &bx);
            one_s += sooc_seconds() - t1;
            one_ev += bx.n_eval;
            n_one++;
        }
        for (int i = 0; !st && sweep && i < nm; i++) {   /* level x resolution sweep on the matched entries */
            const sooc_geom_match *r = &mt[i];
            if (!r->tight) continue;
            for (int a = 0; a < NL && !st; a++)
                for (int b = 0; b < NR && !st; b++) {
                    sooc_objgeom_opts o;
                    sooc_objgeom_opts_default(&o);
                    o.level = levels[a], o.res = ress[b];
                    sooc_objgeom_box bx;
                    st = sooc_objgeom_entry_box(sooc_mapper_model(mp), sooc_mapper_cogmap(mp), ent[r->entry].id,
                                                &o, &bx);
                    double e = 0;
                    for (int k = 0; k < 3; k++) e += fabs(bx.hi[k] - bx.lo[k] - r->ext_gt[k]);
                    if (!(sw[a][b] = realloc(sw[a][b], (size_t)(n_sw + 1) * sizeof(double)))) st = SOOC_ENOMEM;
                    else sw[a][b][n_sw] = 100.0 * e / 3.0;
                }
            n_sw++;
        }
        sooc_mapper_destroy(mp);
        if (st) {
            sooc_scene_free(&sc);
            goto fail;
        }
        n_gt += sc.n_objects;
        n_match += nm;
        for (int i = 0; i < nm; i++) {
            const sooc_geom_match *r = &mt[i];
            const sooc_map_entry *e = &ent[r->entry];
            if (n_ext == cap_ext) {
                cap_ext = cap_ext ? 2 * cap_ext : 256;
                ext = realloc(ext, (size_t)cap_ext * sizeof *ext);
                hgt = realloc(hgt, (size_t)cap_ext * sizeof *hgt);
                if (!ext || !hgt) {
                    st = SOOC_ENOMEM;
                    sooc_scene_free(&sc);
                    goto fail;
                }
            }
            if (r->tight) {
                ext[n_ext] = r->ext_err_cm;
                hgt[n_ext++] = r->height_err_cm;
            }
            n_ax += 2;
            n_in += (fabs(r->err_x) <= r->sig_x) + (fabs(r->err_z) <= r->sig_z);
            if (r->tight) {
                n_sym++;
                n_sym_ok += r->sym_pred == r->sym_gt;
            }
            if (fc) {
                double rn = e->geom.reg_n, cy = cos(e->yaw), sy = sin(e->yaw);
                /* the tight box centre in the world (p_world = R_y(yaw) p_obj + (x, 0, z)) */
                double bx = e->x + cy * e->geom.centre[0] + sy * e->geom.centre[2];
                double bz = e->z - sy * e->geom.centre[0] + cy * e->geom.centre[2];
                fprintf(fc, "%d,%d,%s,%.4f,%.3f,%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f,%.5f,%.5f,%.5f,%.5f,%.4f,%u,%.6g,%.6g,%u,%d,%d,%.3f,%.5f,%.5f\n",
                        s, sc.objects[r->gt_index].id, sooc_shape_name(sc.objects[r->gt_index].shape), r->dist_m,
                        r->ext_err_cm, r->height_err_cm, r->ext_pred[0], r->ext_pred[1], r->ext_pred[2],
                        r->ext_gt[0], r->ext_gt[1], r->ext_gt[2], r->err_x, r->err_z, r->sig_x, r->sig_z,
                        2.0 * log(e->sigma_t), e->geom.reg_n, rn > 1 ? e->geom.reg_m2[0] / (rn - 1) : 0.0,
                        rn > 1 ? e->geom.reg_m2[2] / (rn - 1) : 0.0, e->obs_count, r->sym_pred, r->sym_gt,
                        (double)e->geom.sym_iou, bx - sc.objects[r->gt_index].x, bz - sc.objects[r->gt_index].z);
            }
        }
        fprintf(stderr, "bench_geometry: scene %d/%d: %zu entries, %d of %d GT objects matched\n", s + 1, ns, n, nm,
                sc.n_objects);
        sooc_scene_free(&sc);
    }
    double med_ext = median(ext, n_ext), med_h = median(hgt, n_ext);
    for (int a = 0; sweep && a < NL; a++) {
        printf("sweep level %.2f:", (double)levels[a]);
        for (int b = 0; b < NR; b++) printf("  res %d %.2f cm", ress[b], median(sw[a][b], n_sw));
        printf("\n");
    }
    double upd_g = n_upd_geo ? 1e3 * upd_geo / n_upd_geo : NAN, upd_0 = n_upd_none ? 1e3 * upd_none / n_upd_none : NAN;
    printf("extent error (median over %d matched objects with a tight box): %.2f cm; height error %.2f cm\n", n_ext,
           med_ext, med_h);
    printf("position errors within one sigma: %ld of %ld axes (%.3f)\n", n_in, n_ax, n_ax ? (double)n_in / n_ax : NAN);
    printf("symmetry flag agrees with the GT shape: %ld of %ld\n", n_sym_ok, n_sym);
    printf("mapper update: %.2f ms with geometry budget %d, %.2f ms without; %.2f ms per tight box (final refresh)\n",
           upd_g, budget, upd_0, n_boxes ? 1e3 * box_s / n_boxes : NAN);
    printf("one box: %.2f ms, %.0f field evaluations (%ld boxes timed)\n", n_one ? 1e3 * one_s / n_one : NAN,
           n_one ? (double)one_ev / n_one : NAN, n_one);
    printf("{\"bench\": \"geometry\", \"box_evals\": %.0f, \"box_ms_timed\": %.3f, \"scenes\": %d, \"gt_objects\": %ld, \"matched\": %ld, \"extent_err_cm\": %.3f, "
           "\"height_err_cm\": %.3f, \"sigma1_frac\": %.4f, \"symmetric_agree\": %.4f, \"update_ms_geometry\": %.3f, "
           "\"update_ms_plain\": %.3f, \"box_ms\": %.3f, \"budget\": %d}\n",
           n_one ? (double)one_ev / n_one : NAN, n_one ? 1e3 * one_s / n_one : NAN, ns, n_gt, n_match, med_ext, med_h, n_ax ? (double)n_in / n_ax : NAN, n_sym ? (double)n_sym_ok / n_sym : NAN,
           upd_g, upd_0, n_boxes ? 1e3 * box_s / n_boxes : NAN, budget);
fail:
    for (int a = 0; a < NL; a++)
        for (int b = 0; b < NR; b++) free(sw[a][b]);
    if (fc) fclose(fc);
    free(ext);
    free(hgt);
    sooc_free(ent);
    sooc_free(mt);
    sooc_dataset_destroy(ds);
    sooc_model_destroy(m);
    if (st) {
        fprintf(stderr, "bench_geometry: %s\n", sooc_errmsg());
        return 1;
    }
    return 0;
}
