/* `sooc3d eval` on recorded sequences: read each sequence through the one
 * frame path (frame.h) at the model's resolution, attach labels
 * (label-fusion segm.png or mask.png, or the generic instance/ layout, resized with the
 * frames' crop), run sooc_eval_real_run per (model, sequence), and write one
 * JSON cell per pair (docs/metrics.md "Real sequences"). */
#include "cli.h"
#include "cmd_eval_real.h"
#include "sooc3d/mapper.h"
#include "sooc3d/core.h"
#include "sooc3d/model.h"
#include "sooc3d/frame.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

const char *const sooc_eval_real_cli_help =
    "Recorded sequences (a DIR with no scene.yaml and no scene_* folders: 7-Scenes, label-fusion, TUM,\n"
    "...; docs/metrics.md \"Real sequences\"): every N-th frame is a held-out query frame (position\n"
    "% N == N/2; never mapped), the others are mapped in order with a fresh map; the query frames are\n"
    "rendered from the map and scored (depth / RGB RMSE; mIoU and per-object IoU when the sequence has\n"
    "labels: frame-NNNNNN.segm.png, frame-NNNNNN.mask.png, instance/, YCB-Video NNNNNN-label.png, or\n"
    "APC masks/, which are predictions: scores against them are agreement; docs/formats.md); then churn,\n"
    "growth on a second pass over the same frames, yaw / position spread of persistent entries and the\n"
    "free-space / never-seen fractions. One JSON cell per (model, sequence) with \"scale\": \"real\",\n"
    "\"view\": \"Q\".\n"
    "  --query-every N   N of the query rule (default 5)\n"
    "  --no-second-pass  skip the growth pass\n"
    "  --seen-tol M      surface band of the free-space test in m (default 0.25)\n"
    "  --seen-height M   entries without a tight box of their density are tested at this height above\n"
    "                    the support plane in m (default 0.1); the others over their box\n"
    "  --no-own-surface  skip the second free-space test, by each entry's own surface (its mesh's\n"
    "                    vertices: JSON free_frac_own, never_seen_frac_own)\n"
    "  --persist-min K   registrations that make an entry persistent for the spread (default 3)\n"
    "  --panels DIR      DIR/<sequence>/<model>/: a panel PNG (GT | reconstruction | segmentation |\n"
    "                    ... ) and a views.csv row (per-view metrics) per query frame\n";

int sooc_eval_dir_is_recorded(const char *dir) {
    char p[4096];
    if (sooc_path_join(p, sizeof p, dir, "scene.yaml") == SOOC_OK && sooc_file_exists(p)) return 0;
    sooc_clearerr();
    DIR *d = opendir(dir);
    if (!d) return 1;   /* the frame path names the problem */
    struct dirent *de;
    int rec = 1;
    while ((de = readdir(d)))
        if (!strncmp(de->d_name, "scene_", 6)) rec = 0;
    closedir(d);
    return rec;
}

typedef enum { LAB_NONE = 0, LAB_READER, LAB_SEGM, LAB_MASK, LAB_INSTANCE } lab_src;
static const char *lab_name(lab_src s) {
    switch (s) {
    case LAB_READER: return "the sequence reader (instance/, YCB-Video label.png, APC masks)";
    case LAB_SEGM: return "frame-NNNNNN.segm.png (label-fusion)";
    case LAB_MASK: return "frame-NNNNNN.mask.png (label-fusion masks, one object)";
    case LAB_INSTANCE: return "instance/frame-NNNNNN.png";
    default: return "none";
    }
}

/* "1 name, 2 name, ..." for the ids of the frames' labels that the reader
 * names (APC objects, YCB-Video classes); "" when it names none. */
static void reader_label_names(const sooc_seq *s, const sooc_frame *fr, int n, char *buf, size_t cap) {
    static uint8_t seen[65536];
    memset(seen, 0, sizeof seen);
    for (int i = 0; i < n; i++)
        for (int k = 0; fr[i].instance && k < fr[i].width * fr[i].height; k++) seen[fr[i].instance[k]] = 1;
    size_t m = 0;
    buf[0] = 0;
    for (int id = 1; id < 65536 && m + 1 < cap; id++) {
        const char *nm = seen[id] ? sooc_seq_label_name(s, id) : NULL;
        if (nm) {
            int k = snprintf(buf + m, cap - m, "%s%d %s", m ? ", " : "", id, nm);
            if (k < 0) break;
            m += (size_t)k;
        }
    }
}

/* Read every frame of dir at model c's input size into *frames (count *n)
 * with labels on the query frames of the rule when the sequence has them;
 * *pred = 1 when the reader's labels are predictions (APC masks), names =
 * the reader's names of the label ids. */
static sooc_status load_sequence(const char *dir, const sooc_framepath_params *fpp0, const sooc_model_config *c,
                                 int every, sooc_frame **frames, int *n_out, lab_src *lab, int *pred, char *names,
                                 size_t ncap) {
    sooc_framepath_params fpp = *fpp0;
    sooc_cli_framepath_model(&fpp, c);
    int w = c->img_w, h = c->img_h;
    sooc_framepath *fp = NULL;
    sooc_frame *fr = NULL;
    int n = 0;
    uint16_t *ids = NULL;
    *lab = LAB_NONE;
    *pred = 0;
    names[0] = 0;
    sooc_status st = sooc_framepath_open(&fp, dir, &fpp);
    if (st) return st;
    int64_t cnt = sooc_framepath_count(fp);
    if (cnt > 1000000) {
        st = sooc_seterr(SOOC_EINVAL, "%s: %lld frames, at most 1000000", dir, (long long)cnt);
        goto done;
    }
    n = (int)cnt;
    if (!(fr = sooc_calloc(n ? (size_t)n : 1, sizeof *fr))) { st = SOOC_ENOMEM; goto done; }
    int fmt = sooc_seq_get_format(sooc_framepath_seq(fp));
    char p[4096];
    /* the 7-Scenes layout (label-fusion too): frame.index is the file's number */
    int seven = fmt == SOOC_SEQ_7SCENES || fmt == SOOC_SEQ_LABELFUSION;
    for (int i = 0; i < n; i++) {
        if ((st = sooc_framepath_read(fp, i, &fr[i]))) goto done;
        if (seven && i == 0) {
            if (sooc_path_join(p, sizeof p, dir, "instance") == SOOC_OK && sooc_dir_exists(p)) *lab = LAB_INSTANCE;
            else {
                snprintf(p, sizeof p, "%s/frame-%06lld.segm.png", dir, (long long)fr[0].index);
                if (sooc_file_exists(p)) *lab = LAB_SEGM;
                snprintf(p, sizeof p, "%s/frame-%06lld.mask.png", dir, (long long)fr[0].index);
                if (*lab == LAB_NONE && sooc_file_exists(p)) *lab = LAB_MASK;
            }
        }
        if (fr[i].instance && i == 0) *lab = LAB_READER;
        if (*lab == LAB_READER && !fr[i].instance) {
            st = sooc_seterr(SOOC_EFORMAT, "%s: frame %d has no instance image while frame 0 has one", dir, i);
            goto done;
        }
        if ((*lab != LAB_SEGM && *lab != LAB_MASK && *lab != LAB_INSTANCE) || !sooc_eval_real_is_query(i, every))
            continue;
        if (*lab == LAB_SEGM || *lab == LAB_MASK)
            snprintf(p, sizeof p, "%s/frame-%06lld.%s.png", dir, (long long)fr[i].index,
                     *lab == LAB_SEGM ? "segm" : "mask");
        else snprintf(p, sizeof p, "%s/instance/frame-%06lld.png", dir, (long long)fr[i].index);
        int lw = 0, lh = 0;
        if ((st = sooc_eval_labels_read(p, &ids, &lw, &lh))) goto done;
        if (!(fr[i].instance = sooc_malloc((size_t)w * (size_t)h * sizeof *fr[i].instance))) {
            st = SOOC_ENOMEM;
            goto done;
        }
        /* the same crop and nearest sampling as the frame; fails unless the
         * labels have the frame's own size */
        if ((st = sooc_framepath_resize_ids(fp, ids, lw, lh, fr[i].instance))) {
            sooc_adderr(st, "%s", p);
            goto done;
        }
    }
    if (*lab == LAB_READER) {
        *pred = sooc_seq_labels_predicted(sooc_framepath_seq(fp));
        reader_label_names(sooc_framepath_seq(fp), fr, n, names, ncap);
    }
    if (sooc_framepath_empty_depth(fp) > 0)
        sooc_log(SOOC_LOG_WARN, "%s: %lld frames have no valid depth after preprocessing (depth scale or range?)", dir,
                 (long long)sooc_framepath_empty_depth(fp));
done:
    sooc_free(ids);
    sooc_framepath_close(fp);
    if (st) {
        for (int i = 0; fr && i < n; i++) sooc_frame_free(&fr[i]);
        sooc_free(fr);
        return st;
    }
    *frames = fr, *n_out = n;
    return SOOC_OK;
}

/* --panels: one panel and one CSV row per scored query frame. */
typedef struct panel_ctx {
    const char *dir;
    FILE *csv;
    double d_clip;
} panel_ctx;

static sooc_status on_query(void *user, const sooc_eval_view_info *v) {
    panel_ctx *P = user;
    const sooc_view_metrics *m = v->metrics;
    fprintf(P->csv, "%lld,%d,%d,%.6f,%.6f,%.6f,%.6f,%zu\n", (long long)v->gt->index, v->frame, v->n_comp,
            m->miou_best, m->miou_hung, m->rgb_rmse, m->depth_rmse, m->n_valid_pixels);
    sooc_panel_opts po;
    sooc_panel_opts_default(&po);
    uint32_t ids[SOOC_RENDER_MAX_COMP];
    for (int k = 0; k < v->n_comp && k < SOOC_RENDER_MAX_COMP; k++) ids[k] = (uint32_t)v->comp_ids[k];
    po.comp_ids = ids;
    po.d_clip = P->d_clip;
    char title[160], path[4096];
    if (isfinite(m->miou_best))
        snprintf(title, sizeof title, "frame %lld (query) mIoU %.2f rgb %.3f depth %.2f m", (long long)v->gt->index,
                 m->miou_best, m->rgb_rmse, m->depth_rmse);
    else
        snprintf(title, sizeof title, "frame %lld (query) rgb %.3f depth %.2f m", (long long)v->gt->index, m->rgb_rmse,
                 m->depth_rmse);
    po.title = title;
    sooc_image img;
    memset(&img, 0, sizeof img);
    sooc_status st = sooc_eval_panel(&img, v->gt, v->render, &po);
    snprintf(path, sizeof path, "%s/query_%06lld.png", P->dir, (long long)v->gt->index);
    if (!st) st = sooc_png_write(path, &img, 6);
    sooc_image_free(&img);
    return st;
}

static const char *seq_name(const char *dir, char *buf, size_t cap) {
    size_t n = strlen(dir);
    while (n > 1 && dir[n - 1] == '/') n--;
    size_t s = n;
    while (s > 0 && dir[s - 1] != '/') s--;
    snprintf(buf, cap, "%.*s", (int)(n - s), dir + s);
    return buf;
}

static void fmt_num(char *b, size_t cap, double v, int dec) {
    if (isfinite(v)) snprintf(b, cap, "%.*f", dec, v);
    else snprintf(b, cap, "-");
}

/* One row of the text / Markdown table. */
static void row_cells(const sooc_eval_real_result *r, int pass2, char c[10][48]) {
    sooc_metric_means mm;
    sooc_metric_sums_means(&r->query, &mm);
    double ne = (double)(r->n_seen[0] + r->n_seen[1] + r->n_seen[2]);
    snprintf(c[0], 48, "%d/%d", r->n_mapped, r->n_query);
    fmt_num(c[1], 48, mm.depth_rmse, 3);
    fmt_num(c[2], 48, mm.rgb_rmse, 3);
    fmt_num(c[3], 48, r->has_labels ? mm.miou_best : NAN, 3);
    snprintf(c[4], 48, "%zu/%ld", r->entries_final, r->churn.created);
    if (pass2 && r->entries_final)
        snprintf(c[5], 48, "%+.2f", ((double)r->entries_pass2 - (double)r->entries_final) / (double)r->entries_final);
    else snprintf(c[5], 48, "-");
    fmt_num(c[6], 48, r->pos_spread_m, 3);
    fmt_num(c[7], 48, r->yaw_spread_deg, 1);
    fmt_num(c[8], 48, ne > 0 ? r->n_seen[SOOC_SEEN_FREE] / ne : NAN, 2);
    fmt_num(c[9], 48, ne > 0 ? r->n_seen[SOOC_SEEN_NEVER] / ne : NAN, 2);
}

static const char *const k_cols[10] = {"mapped/query", "depth RMSE", "RGB RMSE", "mIoU",     "entries end/created",
                                       "growth",       "pos spread", "yaw spread", "free", "never seen"};

/* --finetune progress: one overwritten line per unit. */
static int on_ft_progress(void *user, const sooc_finetune_progress *p) {
    (void)user;
    fprintf(stderr, "\reval: finetuning unit %d/%d: step %d/%d loss %.4f %.0f steps/s ETA %.0f s   ", p->unit + 1,
            p->n_units, p->iter, p->iterations, p->loss, p->steps_per_s, p->eta_s);
    if (p->iter == p->iterations && p->unit + 1 == p->n_units) fputc('\n', stderr);
    return 0;
}

/* One (model, sequence) cell: the run, its panels and its JSON. */
/* m NULL: the geometric baseline, with the clip of model clip_of */
static sooc_status run_cell(const sooc_eval_real_cli *a, sooc_model *m, sooc_model *clip_of, const char *name,
                            const char *dir,
                            const sooc_eval_real_opts *o, sooc_frame *fr, int nfr, sooc_eval_real_result *r,
                            char **cell) {
    const sooc_model_config *c = sooc_model_get_config(m ? m : clip_of);
    char sn[256], pdir[4096];
    seq_name(dir, sn, sizeof sn);
    panel_ctx pc = {pdir, NULL, o->run.d_clip > 0 ? o->run.d_clip : c->d_clip * c->unit_m};
    sooc_status st;
    if (a->panels) {
        snprintf(pdir, sizeof pdir, "%s/%s/%s", a->panels, sn, name);
        char cp[4200];
        snprintf(cp, sizeof cp, "%s/views.csv", pdir);
        if ((st = sooc_mkdirs(pdir))) return st;
        if (!(pc.csv = fopen(cp, "w"))) return sooc_seterr(SOOC_EIO, "%s: cannot open for writing", cp);
        fprintf(pc.csv, "frame,position,n_comp,miou_best,miou_hung,rgb_rmse,depth_rmse,valid_pixels\n");
    }
    if (m) st = sooc_eval_real_run(m, fr, nfr, o, pc.csv ? on_query : NULL, &pc, r);
    else st = sooc_eval_geometric_run(fr, nfr, o, NULL, pc.d_clip, pc.csv ? on_query : NULL, &pc, r);
    if (pc.csv && fclose(pc.csv) && !st) st = sooc_seterr(SOOC_EIO, "%s/views.csv: write failed", pdir);
    if (st) return sooc_adderr(st, "%s", dir);
    if ((st = sooc_eval_real_json(name, sn, dir, o, r, cell))) return st;
    if (!a->quiet) {
        fprintf(stderr, "eval: %s on %s: %d mapped, %d query frames, %.1f s mapping (%s), %.1f s rendering", name, sn,
                r->n_mapped, r->n_query, r->update_s, sooc_eval_real_second_pass(o) ? "two passes" : "one pass",
                r->render_s);
        if (o->finetune) fprintf(stderr, ", %.1f s finetuning", r->finetune_s);
        if (!m) fprintf(stderr, " (geometric: %zu objects)", r->entries_final);
        if (o->finetune && o->run.birth) fprintf(stderr, " (%d entries born, %d removed after it)", r->n_born, r->n_pruned);
        fputc('\n', stderr);
    }
    return SOOC_OK;
}

int sooc_cmd_eval_real(const sooc_eval_real_cli *a) {
    sooc_status st = SOOC_OK;
    sooc_model *m = NULL;
    sooc_frame *fr = NULL;
    int nfr = 0;
    char **cells = NULL;
    int n_cells = 0;
    char *md = NULL;
    size_t md_len = 0, md_cap = 0;
    sooc_eval_real_result *res = NULL;
    typedef struct { char model[160], seq[256]; int pass2, pred; } row_name;
    row_name *rn = NULL;
    size_t cap = (2 * (size_t)a->n_models + 1) * (size_t)a->n_dirs;   /* a base and a +ft row each, geometric */
    if (!(cells = calloc(cap, sizeof *cells)) || !(res = calloc(cap, sizeof *res)) || !(rn = calloc(cap, sizeof *rn))) {
        free(cells);
        free(res);
        return sooc_cli_fail("eval", SOOC_ENOMEM);
    }
    double t0 = sooc_seconds(), ft_s = 0;
    for (int mi = 0; mi < a->n_models && !st; mi++) {
        if ((st = sooc_model_load(&m, a->models[mi], NULL, NULL))) break;
        const sooc_model_config *c = sooc_model_get_config(m);
        int with_ft = a->ft && !sooc_model_is_global(m);
        for (int d = 0; d < a->n_dirs && !st; d++) {
            lab_src lab;
            int pred;
            char lnames[2048];
            if ((st = load_sequence(a->dirs[d], &a->fp, c, a->opts.query_every, &fr, &nfr, &lab, &pred, lnames,
                                    sizeof lnames))) {
                sooc_adderr(st, "%s", a->dirs[d]);
                break;
            }
            if (!a->quiet)
                fprintf(stderr, "eval: %s on %s: %d frames at %dx%d, labels: %s%s%s%s\n", a->names[mi], a->dirs[d],
                        nfr, c->img_w, c->img_h, lab_name(lab),
                        pred ? ", PREDICTED masks (scores are agreement with them, not accuracy)" : "",
                        lnames[0] ? "; ids: " : "", lnames);
            sooc_eval_real_opts og = a->opts;   /* the geometric row's */
            og.labels_predicted = pred;
            for (int ft = 0; ft <= with_ft && !st; ft++) {
                sooc_eval_real_opts o = og;
                o.finetune = ft ? a->ft : NULL;
                o.ft_progress = ft && !a->quiet ? on_ft_progress : NULL;
                row_name *r = &rn[n_cells];
                snprintf(r->model, sizeof r->model, "%.150s%s", a->names[mi], ft ? "+ft" : "");
                seq_name(a->dirs[d], r->seq, sizeof r->seq);
                r->pass2 = sooc_eval_real_second_pass(&o);
                r->pred = pred;
                st = run_cell(a, m, m, r->model, a->dirs[d], &o, fr, nfr, &res[n_cells], &cells[n_cells]);
                if (!st) ft_s += res[n_cells++].finetune_s;
            }
            if (a->geometric && mi == 0 && !st) {   /* the baseline on the first model's frames */
                row_name *r = &rn[n_cells];
                snprintf(r->model, sizeof r->model, "geometric");
                seq_name(a->dirs[d], r->seq, sizeof r->seq);
                r->pass2 = 0;
                r->pred = pred;
                st = run_cell(a, NULL, m, r->model, a->dirs[d], &og, fr, nfr, &res[n_cells], &cells[n_cells]);
                if (!st) n_cells++;
            }
            for (int i = 0; i < nfr; i++) sooc_frame_free(&fr[i]);
            sooc_free(fr);
            fr = NULL;
        }
        sooc_model_destroy(m);
        m = NULL;
    }
    if (st) goto fail;

    /* text table on stdout, Markdown alongside */
    {
        size_t need = 4096 + (size_t)n_cells * 1600;   /* a row and a per-object IoU line each */
        if (!(md = malloc(need))) { st = SOOC_ENOMEM; goto fail; }
        md_cap = need;
        md_len += (size_t)snprintf(md + md_len, md_cap - md_len,
                                   "| model | sequence | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n"
                                   "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
                                   k_cols[0], k_cols[1], k_cols[2], k_cols[3], k_cols[4], k_cols[5], k_cols[6],
                                   k_cols[7], k_cols[8], k_cols[9]);
        printf("%-16s %-20s %12s %10s %9s %6s %19s %7s %10s %10s %5s %10s\n", "model", "sequence", k_cols[0], k_cols[1],
               k_cols[2], k_cols[3], k_cols[4], k_cols[5], k_cols[6], k_cols[7], k_cols[8], k_cols[9]);
        for (int k = 0; k < n_cells; k++) {
            char cc[10][48];
            row_cells(&res[k], rn[k].pass2, cc);
            printf("%-16s %-20s %12s %10s %9s %6s %19s %7s %10s %10s %5s %10s\n", rn[k].model, rn[k].seq, cc[0], cc[1],
                   cc[2], cc[3], cc[4], cc[5], cc[6], cc[7], cc[8], cc[9]);
            md_len += (size_t)snprintf(md + md_len, md_cap - md_len,
                                       "| %.60s | %.60s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %s |\n",
                                       rn[k].model, rn[k].seq, cc[0], cc[1], cc[2], cc[3], cc[4], cc[5], cc[6], cc[7],
                                       cc[8], cc[9]);
        }
        /* per-object IoU of the labelled cells, and what it measures */
        md_len += (size_t)snprintf(md + md_len, md_cap - md_len, "\n");
        char pseq[512] = "";
        for (int k = 0; k < n_cells; k++) {
            const sooc_eval_real_result *r = &res[k];
            if (!r->has_labels || !r->obj.n) continue;
            char line[1024];
            size_t m = 0;
            double sum = 0;
            int cnt = 0;
            m += (size_t)snprintf(line, sizeof line, "per-object IoU%s, %s on %s (id IoU):",
                                  rn[k].pred ? " (agreement with predicted masks)" : "", rn[k].model, rn[k].seq);
            for (int j = 0; j < r->obj.n && m < sizeof line - 32; j++) {
                double v = sooc_obj_iou_mean(&r->obj, j);
                m += (size_t)snprintf(line + m, sizeof line - m, " %u %.3f", (unsigned)r->obj.id[j], v);
                if (isfinite(v)) sum += v, cnt++;
            }
            if (cnt) snprintf(line + m, sizeof line - m, "; mean %.3f", sum / cnt);
            printf("%s\n", line);
            md_len += (size_t)snprintf(md + md_len, md_cap - md_len, "%s  \n", line);
            if (rn[k].pred && !strstr(pseq, rn[k].seq) && strlen(pseq) + strlen(rn[k].seq) + 3 < sizeof pseq)
                snprintf(pseq + strlen(pseq), sizeof pseq - strlen(pseq), "%s%s", pseq[0] ? ", " : "", rn[k].seq);
        }
        if (pseq[0]) {
            char pn[768];
            snprintf(pn, sizeof pn, "Labels of %s are PREDICTED masks (a segmentation network's, APC layout): its mIoU "
                     "and per-object IoU are agreement with predicted masks, not accuracy against ground truth.", pseq);
            printf("\n%s\n", pn);
            md_len += (size_t)snprintf(md + md_len, md_cap - md_len, "\n*%s*\n", pn);
        }
        char note[1024];
        snprintf(note, sizeof note,
                 "Recorded sequences: query frames = every %d-th frame (position %% %d == %d), never mapped, rendered "
                 "from the map after one pass over the other frames; RGB RMSE sums the channels; depth RMSE in m over "
                 "valid depth <= the clip; mIoU best-match with background (labelled sequences only); growth = "
                 "entries after a second pass over the same frames / entries after the first - 1; spread: RMS floor "
                 "position (m) and circular yaw std (deg) of entries registered by >= %d keyframes; free / never "
                 "seen: fraction of final entries the frames saw as free space / never saw, probed at their tight "
                 "box's centre and face centres (entries without a box at %.2f m above the support plane; surface "
                 "band +-%.2f m); the _own figures by the majority of up to 64 vertices of each entry's own mesh. "
                 "Seed %llu. docs/metrics.md \"Real sequences\".",
                 a->opts.query_every, a->opts.query_every, a->opts.query_every / 2, a->opts.persist_min,
                 a->opts.seen_height, a->opts.seen_tol, (unsigned long long)a->opts.run.seed);
        md_len += (size_t)snprintf(md + md_len, md_cap - md_len, "\n*%s*\n", note);
        printf("\n%s\n", note);
        printf("\neval: %d cell%s in %.1f s\n", n_cells, n_cells == 1 ? "" : "s", sooc_seconds() - t0);
        if (a->ft) printf("eval: finetuning (+ft rows) %.1f s in all\n", ft_s);

        size_t jl = 0;
        for (int i = 0; i < n_cells; i++) jl += strlen(cells[i]) + 8;
        size_t jcap = jl + strlen(note) * 2 + 1024;
        char *js = malloc(jcap);
        if (!js) { st = SOOC_ENOMEM; goto fail; }
        size_t n = 0;
        n += (size_t)snprintf(js + n, jcap - n,
                              "{\"conventions\": {\"rgb_rmse\": \"channel sum\", \"depth_rmse\": \"m, valid depth <= "
                              "d_clip\", \"miou\": \"MulMON best-match, background included, IoU<0.05->0\", "
                              "\"obj_iou\": \"best-match IoU per labelled object id (obj_ids), mean over the query "
                              "frames where it is visible (obj_views)\"}, \"note\": \"");
        for (const char *s = note; *s; s++) {
            if (*s == '"' || *s == '\\') js[n++] = '\\';
            js[n++] = *s;
        }
        n += (size_t)snprintf(js + n, jcap - n, "\", \"cells\": [");
        for (int i = 0; i < n_cells; i++) n += (size_t)snprintf(js + n, jcap - n, "%s\n  %s", i ? "," : "", cells[i]);
        n += (size_t)snprintf(js + n, jcap - n, "\n]}\n");
        st = sooc_file_write_atomic(a->json, js, n);
        free(js);
        if (st) { sooc_adderr(st, "%s", a->json); goto fail; }
        if (a->md && (st = sooc_file_write_atomic(a->md, md, md_len))) { sooc_adderr(st, "%s", a->md); goto fail; }
        printf("eval: wrote %s%s%s\n", a->json, a->md ? " and " : "", a->md ? a->md : "");
    }
fail:
    for (size_t i = 0; i < cap; i++) sooc_free(cells[i]);
    free(cells);
    free(res);
    free(rn);
    free(md);
    sooc_model_destroy(m);
    return st ? sooc_cli_fail("eval", st) : 0;
}
