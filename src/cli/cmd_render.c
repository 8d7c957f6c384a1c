/* sooc3d render: the pictures of one sequence through the
 * evaluation path: a panel per view, the top-down cognitive map over the
 * online run (PNG sequence + contact sheet), training curves. */
#include "cli.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/eval.h"
#include "sooc3d/frame.h"
#include "sooc3d/model.h"
#include "sooc3d/node.h"
#include "sooc3d/gen.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d render --model M --seq DIR --out DIR [--map map.sqlite] [--views N]\n"
            "                     [--uncertainty M] [--log train_dir/log.csv] [--seed S] [--threads T]\n"
            "                     [--samples C,F] [--iterations L] [--input-timing final|online]\n"
            "                     [--max-frames N] [--max-obj K] [--clip D]\n"
            "                     [--calib F] [--format NAME] [--depth-scale S] [--depth-shift N]\n"
            "                     [--min-depth M] [--max-depth M] [--up X,Y,Z] [--world W]\n\n"
            "Runs online inference over the sequence's input views (or, with --map, renders from a map\n"
            "stored by `sooc3d node` / the map store, without updating it) and writes\n"
            "  OUT/panels/view_%%06d.png  one panel per selected view: GT | reconstruction |\n"
            "                            segmentation | GT segmentation | depth | GT depth |\n"
            "                            uncertainty | components (GT segmentation only when\n"
            "                            the sequence has instance ids)\n"
            "  OUT/cogmap/cogmap_%%04d.png, OUT/cogmap/cogmap_sheet.png\n"
            "                            the cognitive map from above after each input view: camera\n"
            "                            frustums and the camera path in the map's world frame,\n"
            "                            entries coloured by id, out-of-view entries grey, GT\n"
            "                            objects (scene.yaml) as outlines\n"
            "  OUT/views.csv             per-view metrics of every rendered view\n"
            "  OUT/curves.png            training curves (with --log)\n\n"
            "  --views         render N views spread evenly over the sequence, a panel each (8; 0 = all)\n"
            "  --metrics-all   also render and score every other view (its row of views.csv, no panel)\n"
            "  --uncertainty   M >= 2 posterior samples for the uncertainty tile (default 0: none)\n"
            "  --input-timing  panels of input views from the final map (final, default) or right\n"
            "                  after their own update (online)\n"
            "  --samples       coarse,fine samples per ray (96,32)\n"
            "  --max-frames    use only the first N frames of the sequence\n"
            "  --max-obj       render at most K in-view objects per view (default: all, up to 63)\n"
            "  --clip          clip depth in metres instead of the model's d_clip (e.g. the sensor's\n"
            "                  usable range): deeper pixels are unscored, deeper objects out of view\n"
            "With --map, the world frame stored in the map (by `sooc3d node`) places the camera.\n\n"
            "%s",
            sooc_cli_framepath_help);
}

typedef struct render_ctx {
    const char *out;
    const sooc_model_config *mc;
    FILE *csv;
    int n_panels;
    sooc_topdown_step *steps;
    int n_steps;
    const uint8_t *detail;
    int timing;
    sooc_progress pr;
    int n_done, n_total;
    int n_nan;                 /* views whose RGB or depth RMSE is not finite */
} render_ctx;

static sooc_status write_panel(render_ctx *R, const sooc_eval_view_info *v) {
    sooc_panel_opts po;
    sooc_panel_opts_default(&po);
    uint32_t ids[SOOC_RENDER_MAX_COMP];
    for (int k = 0; k < v->n_comp; k++) ids[k] = (uint32_t)v->comp_ids[k];
    po.comp_ids = ids;
    po.d_clip = R->mc->d_clip * R->mc->unit_m;   /* metres */
    char title[160], path[1200];
    const sooc_view_metrics *m = v->metrics;
    if (isfinite(m->miou_best))
        snprintf(title, sizeof title, "frame %lld (%s%s) mIoU %.2f rgb %.3f depth %.2f m", (long long)v->gt->index,
                 v->gt->is_query ? "query" : "input", v->online ? ", online" : "", m->miou_best, m->rgb_rmse,
                 m->depth_rmse);
    else
        snprintf(title, sizeof title, "frame %lld (%s%s) rgb %.3f depth %.2f m", (long long)v->gt->index,
                 v->gt->is_query ? "query" : "input", v->online ? ", online" : "", m->rgb_rmse, m->depth_rmse);
    po.title = title;
    sooc_image img;
    memset(&img, 0, sizeof img);
    sooc_status st = sooc_eval_panel(&img, v->gt, v->render, &po);
    snprintf(path, sizeof path, "%s/panels/view_%06lld.png", R->out, (long long)v->gt->index);
    if (!st) st = sooc_png_write(path, &img, 6);
    sooc_image_free(&img);
    if (!st) R->n_panels++;
    return st;
}

static sooc_status on_view(void *user, const sooc_eval_view_info *v) {
    render_ctx *R = user;
    const sooc_view_metrics *m = v->metrics;
    if (R->csv)
        fprintf(R->csv, "%lld,%d,%d,%d,%.6f,%.6f,%.6f,%.6f,%d,%d,%.6f,%.6f\n", (long long)v->gt->index,
                v->gt->is_query, v->online, v->n_comp - 1, m->miou_best, m->miou_hung, m->rgb_rmse, m->depth_rmse,
                m->n_obj_visible, m->n_obj_matched, m->n_obj_matched ? m->l2_sum / m->n_obj_matched : NAN,
                m->rgb_rmse_obj);
    R->n_done++;
    if (!isfinite(m->rgb_rmse) || !isfinite(m->depth_rmse)) R->n_nan++;
    sooc_progress_update(&R->pr, (uint64_t)R->n_done, NULL);
    /* a panel for the flagged views; input views at the chosen timing only */
    if (!R->detail[v->frame]) return SOOC_OK;
    if (!v->gt->is_query && (R->timing == SOOC_EVAL_ONLINE) != v->online) return SOOC_OK;
    return write_panel(R, v);
}

static sooc_status on_step(void *user, const sooc_eval_step_info *s) {
    render_ctx *R = user;
    sooc_topdown_step *t = &R->steps[R->n_steps];
    memcpy(t->T_wc, s->gt->T_wc, sizeof t->T_wc);
    sooc_map_entry *e = malloc((s->n_entries ? s->n_entries : 1) * sizeof *e);
    if (!e) return SOOC_ENOMEM;
    if (s->n_entries) memcpy(e, s->entries, s->n_entries * sizeof *e);   /* entries may be NULL when empty */
    t->entries = e;
    t->n_entries = s->n_entries;
    R->n_steps++;
    return SOOC_OK;
}

/* Every frame with a pose, through the frame path at the model's resolution,
 * poses in the map's world frame. *n_empty: frames without valid depth. */
static sooc_status read_frames(const char *dir, const sooc_framepath_params *fpp, long long maxf, sooc_frame **out,
                               int *n_out, int *resized, int64_t *n_empty, double T_world_src[16]) {
    sooc_framepath *fp = NULL;
    *out = NULL;
    *n_out = 0;
    *resized = 0;
    sooc_status st = sooc_framepath_open(&fp, dir, fpp);
    if (st) return st;
    int64_t n = sooc_framepath_count(fp);
    if (maxf >= 0 && maxf < n) n = maxf;
    sooc_frame *fr = calloc(n ? (size_t)n : 1, sizeof *fr);
    if (!fr) {
        sooc_framepath_close(fp);
        return SOOC_ENOMEM;
    }
    int k = 0;
    for (int64_t i = 0; i < n && !st; i++) {
        if ((st = sooc_framepath_read(fp, i, &fr[k]))) break;
        if (!fr[k].has_pose) continue;
        k++;
    }
    if (!st) {
        const sooc_calib *c = sooc_seq_calib(sooc_framepath_seq(fp));
        *resized = c && c->K.width > 0 && (c->K.width != fpp->width || c->K.height != fpp->height);
        *n_empty = sooc_framepath_empty_depth(fp);
        sooc_framepath_world_get(fp, T_world_src);
    }
    sooc_framepath_close(fp);
    if (st) {
        for (int i = 0; i <= k && i < n; i++) sooc_frame_free(&fr[i]);
        free(fr);
        return st;
    }
    /* a frame read past the last kept one (no pose) */
    if (k < n) sooc_frame_free(&fr[k]);
    *out = fr;
    *n_out = k;
    return SOOC_OK;
}

int sooc_cmd_render(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *model = NULL, *seqdir = NULL, *out = NULL, *mappath = NULL, *logpath = NULL;
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    int fo;
    double clip = 0;
    int views = 8, timing = SOOC_EVAL_FINAL, metrics_all = 0;
    long long maxf = -1;
    sooc_eval_run_opts ro;
    sooc_eval_run_opts_default(&ro);
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
#define INTV(lo, hi, x) do { if (!sooc_cli_int_opt("render", a, argv[++i], lo, hi, x)) return 2; } while (0)
        if (!strcmp(a, "--model") && has) model = argv[++i];
        else if (!strcmp(a, "--seq") && has) seqdir = argv[++i];
        else if (!strcmp(a, "--out") && has) out = argv[++i];
        else if (!strcmp(a, "--map") && has) mappath = argv[++i];
        else if ((fo = sooc_cli_framepath_opt("render", argc, argv, &i, &fpp)) != 0) {
            if (fo < 0) return 2;
        }
        else if (!strcmp(a, "--log") && has) logpath = argv[++i];
        else if (!strcmp(a, "--views") && has) INTV(0, 1000000, &views);
        else if (!strcmp(a, "--metrics-all")) metrics_all = 1;
        else if (!strcmp(a, "--uncertainty") && has) INTV(0, 1000, &ro.uncertainty);
        else if (!strcmp(a, "--seed") && has) { if (!sooc_cli_u64_opt("render", a, argv[++i], UINT64_MAX, &ro.seed)) return 2; }
        else if (!strcmp(a, "--threads") && has) INTV(0, 256, &ro.threads);
        else if (!strcmp(a, "--iterations") && has) INTV(0, 16, &ro.iterations);
        else if (!strcmp(a, "--max-frames") && has) {
            if (!sooc_cli_count_opt("render", a, argv[++i], &maxf)) return 2;
        }
        else if (!strcmp(a, "--max-obj") && has) INTV(0, SOOC_RENDER_MAX_COMP - 1, &ro.max_obj);
        else if (!strcmp(a, "--clip") && has) {
            if (!sooc_cli_double_opt("render", a, argv[++i], 0.01, 1000, &clip)) return 2;
        } else if (!strcmp(a, "--samples") && has) {
            if (!sooc_cli_parse_samples(argv[++i], &ro.n_coarse, &ro.n_fine)) {
                fprintf(stderr, "sooc3d render: --samples wants C[,F] with C >= 2, F >= 0\n");
                return 2;
            }
        } else if (!strcmp(a, "--input-timing") && has) {
            timing = sooc_eval_timing_parse(argv[++i]);
            if (timing != SOOC_EVAL_FINAL && timing != SOOC_EVAL_ONLINE) {
                fprintf(stderr, "sooc3d render: --input-timing must be final or online\n");
                return 2;
            }
        } else {
            fprintf(stderr, "sooc3d render: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
#undef INTV
    }
    if (!model || !seqdir || !out || ro.uncertainty == 1) {
        if (ro.uncertainty == 1) fprintf(stderr, "sooc3d render: --uncertainty needs M >= 2 samples\n");
        usage(stderr);
        return 2;
    }
    if (!sooc_cli_framepath_check("render", &fpp)) return 2;
    ro.timing = (sooc_eval_timing)timing;
    ro.components = 1;

    sooc_status st = SOOC_OK;
    sooc_model *m = NULL;
    sooc_frame *fr = NULL;
    int nf = 0, resized = 0;
    sooc_scene sc;
    sooc_scene_init(&sc);
    int have_scene = 0;
    sooc_gt_object *gt = NULL;
    sooc_fig_gt *fgt = NULL;
    uint8_t *detail = NULL;
    render_ctx R;
    memset(&R, 0, sizeof R);
    sooc_cogmap *map = NULL;
    sooc_mapstore *ms = NULL;
    sooc_map_entry *ment = NULL;
    sooc_render_out rout;
    memset(&rout, 0, sizeof rout);
    char path[1200];

    if ((st = sooc_model_load(&m, model, NULL, NULL))) goto fail;
    if (clip > 0 && (st = sooc_model_set_clip(m, (float)clip))) goto fail;
    const sooc_model_config *mc = sooc_model_get_config(m);
    sooc_cli_framepath_model(&fpp, mc);
    fpp.map_db = mappath;
    int64_t n_empty = 0;
    double T_world_src[16];
    if ((st = read_frames(seqdir, &fpp, maxf, &fr, &nf, &resized, &n_empty, T_world_src))) goto fail;
    if (mappath) {   /* a map made by odometry: its keyframes place the cameras, not the recording's poses */
        int moved = 0;
        int64_t nkf = 0;
        if ((st = sooc_cli_slam_poses(mappath, T_world_src, fr, nf, &moved, &nkf))) goto fail;
        if (moved)
            printf("render: %d cameras placed from the map's %lld tracking keyframes (the recording's poses are "
                   "in another frame)\n", moved, (long long)nkf);
    }
    if (resized) printf("render: frames cropped/resized to the model's %dx%d\n", mc->img_w, mc->img_h);
    if (n_empty > 0)
        fprintf(stderr, "sooc3d render: warning: %lld frames have no valid depth in [%g, %g] m after preprocessing "
                        "(check the depth scale: --calib, --depth-scale, --depth-shift); their depth tiles are "
                        "black and their depth RMSE is nan\n",
                (long long)n_empty, fpp.min_depth_m, fpp.max_depth_m);
    if (nf == 0) {
        st = sooc_seterr(SOOC_EINVAL, "%s: no frame with a pose", seqdir);
        goto fail;
    }
    /* ground truth from scene.yaml, when there is one */
    struct stat sb;
    if ((st = sooc_path_join(path, sizeof path, seqdir, "scene.yaml"))) goto fail;
    if (stat(path, &sb) == 0) {
        if ((st = sooc_scene_load(path, &sc))) goto fail;
        have_scene = 1;
        gt = calloc(sc.n_objects ? (size_t)sc.n_objects : 1, sizeof *gt);
        fgt = calloc(sc.n_objects ? (size_t)sc.n_objects : 1, sizeof *fgt);
        if (!gt || !fgt) { st = SOOC_ENOMEM; goto fail; }
        for (int i = 0; i < sc.n_objects; i++) {
            const sooc_scene_object *o = &sc.objects[i];
            double c[3];
            sooc_scene_object_center(o, c);
            gt[i].id = (uint16_t)o->id, gt[i].x = c[0], gt[i].z = c[2];
            fgt[i].id = (uint16_t)o->id, fgt[i].x = c[0], fgt[i].z = c[2], fgt[i].yaw = o->yaw;
            fgt[i].size_x = o->size[0], fgt[i].size_z = o->size[2];
        }
    }
    /* panel views: evenly spread */
    detail = calloc((size_t)nf, 1);
    if (!detail) { st = SOOC_ENOMEM; goto fail; }
    if (views == 0 || views >= nf) memset(detail, 1, (size_t)nf);
    else
        for (int k = 0; k < views; k++) detail[(int)((k + 0.5) * nf / views)] = 1;
    ro.detail_views = detail;
    if (!metrics_all) ro.render_views = detail;   /* the other views are mapped, not rendered */

    char sub[1200];
    if ((st = sooc_path_join(sub, sizeof sub, out, "panels")) || (st = sooc_mkdirs(sub))) goto fail;
    if ((st = sooc_path_join(path, sizeof path, out, "views.csv"))) goto fail;
    R.csv = fopen(path, "w");
    if (!R.csv) { st = sooc_seterr(SOOC_EIO, "%s: cannot open for writing", path); goto fail; }
    fprintf(R.csv, "frame,is_query,online,n_objects,miou_best,miou_hung,rgb_rmse,depth_rmse,n_obj_visible,"
                   "n_obj_matched,l2,rgb_rmse_obj\n");
    R.out = out, R.mc = mc, R.detail = detail, R.timing = timing;
    R.steps = calloc((size_t)nf, sizeof *R.steps);
    if (!R.steps) { st = SOOC_ENOMEM; goto fail; }

    if (!mappath) {
        R.n_total = nf;
        sooc_progress_begin(&R.pr, "render", (uint64_t)R.n_total);
        sooc_eval_scene_result res;
        st = sooc_eval_run_scene(m, fr, nf, gt, have_scene ? sc.n_objects : 0, &ro, on_view, on_step, &R, &res);
        sooc_progress_end(&R.pr, NULL);
        if (st) goto fail;
        printf("render: %d input views mapped (%.1f ms/update), %zu map entries\n", res.n_mapped,
               res.n_mapped ? 1e3 * res.update_s / res.n_mapped : 0.0, res.n_entries);
    } else {
        /* a stored map: load it (entries, layout blocks, id counter) and render from it */
        if ((st = sooc_cli_open_stored_map(model, mc, mappath, NULL, &ms, &map))) goto fail;
        size_t ne = sooc_cogmap_count(map);
        sooc_cogmap_entry *ce = calloc(ne ? ne : 1, sizeof *ce);
        ment = calloc(ne ? ne : 1, sizeof *ment);
        if (!ce || !ment) { free(ce); st = SOOC_ENOMEM; goto fail; }
        if ((st = sooc_cogmap_entries(map, ce, ne, &ne))) { free(ce); goto fail; }
        {
            float ext[3];
            sooc_model_box_extent(mc, ext);
            for (size_t i = 0; i < ne; i++) sooc_map_entry_from_cogmap(&ce[i], ext, &ment[i]);
        }
        free(ce);
        R.n_total = nf;
        R.timing = SOOC_EVAL_FINAL;
        sooc_progress_begin(&R.pr, "render", (uint64_t)nf);
        for (int i = 0; i < nf && !st; i++) {
            sooc_view_metrics vm;
            sooc_iou_match match;
            uint64_t ids[SOOC_RENDER_MAX_COMP];
            double xz[2 * SOOC_RENDER_MAX_COMP];
            int nc = 0;
            if (!metrics_all && !detail[i]) {   /* not rendered: its camera still goes on the top-down map */
                if (!fr[i].is_query) {
                    sooc_topdown_step *t = &R.steps[R.n_steps++];
                    memcpy(t->T_wc, fr[i].T_wc, sizeof t->T_wc);
                    t->entries = ment;
                    t->n_entries = ne;
                }
                continue;
            }
            st = sooc_eval_map_view(m, map, &fr[i], gt, have_scene ? sc.n_objects : 0, &ro, detail[i], &rout, &vm,
                                    &match, ids, xz, &nc);
            if (st) break;
            sooc_eval_view_info vi = {i, &fr[i], 0, 0, &rout, &vm, fr[i].instance ? &match : NULL, nc, ids, xz};
            if ((st = on_view(&R, &vi))) break;
            if (!fr[i].is_query) {
                sooc_topdown_step *t = &R.steps[R.n_steps++];
                memcpy(t->T_wc, fr[i].T_wc, sizeof t->T_wc);
                t->entries = ment;
                t->n_entries = ne;
            }
        }
        sooc_progress_end(&R.pr, NULL);
        if (st) goto fail;
        printf("render: %zu entries loaded from %s (not updated)\n", ne, mappath);
    }
    fclose(R.csv);
    R.csv = NULL;
    printf("render: %d panels -> %s/panels/\n", R.n_panels, out);
    if (R.n_steps > 0) {
        sooc_topdown_opts to;
        sooc_topdown_opts_default(&to);
        sooc_intrinsics K = fr[0].K;
        K.width = fr[0].width, K.height = fr[0].height;
        to.K = &K;
        to.d_clip = mc->d_clip * mc->unit_m;
        to.title = mappath ? "stored cognitive map" : "cognitive map (online run)";
        {   /* small worlds (a shelf bin, a desk) get more pixels per metre: at least 480 px across */
            double b[4] = {INFINITY, -INFINITY, INFINITY, -INFINITY};
            for (int i = 0; i < R.n_steps; i++) {
                const sooc_topdown_step *t = &R.steps[i];
                double xs[2] = {t->T_wc[3], t->T_wc[11]};
                b[0] = fmin(b[0], xs[0]), b[1] = fmax(b[1], xs[0]), b[2] = fmin(b[2], xs[1]), b[3] = fmax(b[3], xs[1]);
                for (size_t j = 0; j < t->n_entries; j++) {
                    const sooc_map_entry *e = &t->entries[j];
                    b[0] = fmin(b[0], e->x), b[1] = fmax(b[1], e->x), b[2] = fmin(b[2], e->z), b[3] = fmax(b[3], e->z);
                }
            }
            double span = fmax(b[1] - b[0], b[3] - b[2]) + 3.0;   /* the figure's 1.5 m margins */
            if (isfinite(span) && span * to.px_per_m < 480) to.px_per_m = 480 / span;
        }
        if ((st = sooc_path_join(sub, sizeof sub, out, "cogmap"))) goto fail;
        if ((st = sooc_eval_topdown_sequence(sub, R.steps, R.n_steps, fgt, have_scene ? sc.n_objects : 0, &to)))
            goto fail;
        printf("render: %d top-down maps + contact sheet -> %s/\n", R.n_steps, sub);
    }
    if (logpath) {
        if ((st = sooc_path_join(path, sizeof path, out, "curves.png"))) goto fail;
        if ((st = sooc_eval_plot_csv(logpath, path, "training curves"))) goto fail;
        printf("render: training curves -> %s\n", path);
    }
    printf("render: per-view metrics -> %s/views.csv%s\n", out,
           have_scene ? "" : " (no scene.yaml: no GT segmentation, no mIoU / L2)");
    if (R.n_nan)
        fprintf(stderr, "sooc3d render: warning: %d of %d views have a non-finite RGB or depth RMSE (no valid "
                        "depth to score: check the depth scale and --min-depth/--max-depth)\n",
                R.n_nan, R.n_done);

fail:
    if (R.csv) fclose(R.csv);
    if (R.steps && !mappath)
        for (int i = 0; i < R.n_steps; i++) free((void *)R.steps[i].entries);
    free(R.steps);
    free(ment);
    sooc_render_out_free(&rout);
    sooc_cogmap_destroy(map);
    sooc_mapstore_close(ms);
    free(detail);
    free(gt);
    free(fgt);
    sooc_scene_free(&sc);
    for (int i = 0; i < nf; i++) sooc_frame_free(&fr[i]);
    free(fr);
    sooc_model_destroy(m);
    return st ? sooc_cli_fail_map("render", st) : 0;
}
