/* The paper's Table 1: accumulation per model x scale x {I,Q} x run, mean +- std over runs. */
#include "sooc3d/eval.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

typedef struct entry {
    char *model;
    int scale, run;
    sooc_metric_sums s[2];
} entry;

struct sooc_eval_table {
    entry *e;
    int n, cap;
    char *note;
    int l2_input;
};

sooc_status sooc_eval_table_create(sooc_eval_table **out) {
    *out = sooc_calloc(1, sizeof **out);
    return *out ? SOOC_OK : sooc_seterr(SOOC_ENOMEM, "eval table: out of memory");
}

void sooc_eval_table_destroy(sooc_eval_table *t) {
    if (!t) return;
    for (int i = 0; i < t->n; i++) sooc_free(t->e[i].model);
    sooc_free(t->e);
    sooc_free(t->note);
    sooc_free(t);
}

sooc_status sooc_eval_table_set_note(sooc_eval_table *t, const char *note) {
    sooc_free(t->note);
    t->note = note ? sooc_strdup(note) : NULL;
    return note && !t->note ? sooc_seterr(SOOC_ENOMEM, "eval table: out of memory") : SOOC_OK;
}

static sooc_status get_entry(sooc_eval_table *t, const char *model, int scale, int run, entry **out) {
    if (!model || !*model) return sooc_seterr(SOOC_EINVAL, "eval table: empty model name");
    if (scale < 0 || scale >= SOOC_N_SCALES) return sooc_seterr(SOOC_EINVAL, "eval table: bad scale %d", scale);
    for (int i = 0; i < t->n; i++)
        if (t->e[i].scale == scale && t->e[i].run == run && !strcmp(t->e[i].model, model)) {
            *out = &t->e[i];
            return SOOC_OK;
        }
    if (t->n == t->cap) {
        int nc = t->cap ? 2 * t->cap : 16;
        entry *ne = sooc_realloc(t->e, (size_t)nc * sizeof *ne);
        if (!ne) return sooc_seterr(SOOC_ENOMEM, "eval table: out of memory");
        t->e = ne;
        t->cap = nc;
    }
    entry *e = &t->e[t->n];
    memset(e, 0, sizeof *e);
    e->model = sooc_strdup(model);
    if (!e->model) return sooc_seterr(SOOC_ENOMEM, "eval table: out of memory");
    e->scale = scale;
    e->run = run;
    t->n++;
    *out = e;
    return SOOC_OK;
}

sooc_status sooc_eval_table_add_view(sooc_eval_table *t, const char *model, int scale, int run,
                                     const sooc_view_metrics *v) {
    entry *e;
    sooc_status s = get_entry(t, model, scale, run, &e);
    if (s) return s;
    sooc_metric_sums_add_view(&e->s[v->is_query ? 1 : 0], v);
    return SOOC_OK;
}

sooc_status sooc_eval_table_add_sums(sooc_eval_table *t, const char *model, int scale, int run,
                                     int is_query, const sooc_metric_sums *sm) {
    entry *e;
    sooc_status s = get_entry(t, model, scale, run, &e);
    if (s) return s;
    sooc_metric_sums_merge(&e->s[is_query ? 1 : 0], sm);
    return SOOC_OK;
}

/* mean and sample std of the finite values */
static void stat_of(const double *v, int n, sooc_eval_stat *s) {
    double m = 0;
    int k = 0;
    for (int i = 0; i < n; i++) if (isfinite(v[i])) { m += v[i]; k++; }
    s->n_runs = k;
    if (!k) { s->mean = s->std = NAN; return; }
    m /= k;
    double q = 0;
    for (int i = 0; i < n; i++) if (isfinite(v[i])) q += (v[i] - m) * (v[i] - m);
    s->mean = m;
    s->std = k > 1 ? sqrt(q / (k - 1)) : 0.0;
}

#define MAX_RUNS 1024
sooc_status sooc_eval_table_cell(const sooc_eval_table *t, const char *model, int scale, int is_query,
                                 sooc_eval_cell *out) {
    memset(out, 0, sizeof *out);
    enum { NG = 9 + SOOC_METRIC_N_DBINS, NM = NG + 3 };
    static _Thread_local double vals[NM][MAX_RUNS];
    double by_sum[SOOC_METRIC_N_OBINS] = {0};
    int n = 0;
    for (int i = 0; i < t->n; i++) {
        const entry *e = &t->e[i];
        if (e->scale != scale || strcmp(e->model, model)) continue;
        const sooc_metric_sums *s = &e->s[is_query ? 1 : 0];
        if (!s->n_views) continue;
        if (n >= MAX_RUNS) return sooc_seterr(SOOC_EINVAL, "eval table: more than %d runs", MAX_RUNS);
        sooc_metric_means m;
        sooc_metric_sums_means(s, &m);
        vals[0][n] = m.miou_best; vals[1][n] = m.miou_hung; vals[2][n] = m.rgb_rmse;
        vals[3][n] = m.depth_rmse; vals[4][n] = m.l2; vals[5][n] = m.matched_frac;
        vals[6][n] = m.mesh_acc_cm; vals[7][n] = m.mesh_comp_cm; vals[8][n] = m.rgb_rmse_obj;
        for (int b = 0; b < SOOC_METRIC_N_DBINS; b++) vals[9 + b][n] = m.recall[b];
        vals[NG][n] = m.extent_err_cm; vals[NG + 1][n] = m.sigma1_frac; vals[NG + 2][n] = m.symmetric_agree;
        for (int b = 0; b < SOOC_METRIC_N_OBINS; b++) {
            by_sum[b] += s->miou_by_nobj[b];
            out->n_by_nobj[b] += s->n_by_nobj[b];
        }
        out->n_views += s->n_views;
        n++;
    }
    if (!n) return SOOC_ENOTFOUND;   /* no message: absence is a normal answer */
    stat_of(vals[0], n, &out->miou_best); stat_of(vals[1], n, &out->miou_hung);
    stat_of(vals[2], n, &out->rgb_rmse); stat_of(vals[3], n, &out->depth_rmse);
    stat_of(vals[4], n, &out->l2); stat_of(vals[5], n, &out->matched_frac);
    stat_of(vals[6], n, &out->mesh_acc_cm); stat_of(vals[7], n, &out->mesh_comp_cm);
    stat_of(vals[8], n, &out->rgb_rmse_obj);
    for (int b = 0; b < SOOC_METRIC_N_DBINS; b++) stat_of(vals[9 + b], n, &out->recall[b]);
    stat_of(vals[NG], n, &out->extent_err_cm); stat_of(vals[NG + 1], n, &out->sigma1_frac);
    stat_of(vals[NG + 2], n, &out->symmetric_agree);
    for (int b = 0; b < SOOC_METRIC_N_OBINS; b++)
        out->miou_by_nobj[b] = out->n_by_nobj[b] ? by_sum[b] / (double)out->n_by_nobj[b] : NAN;
    return SOOC_OK;
}

sooc_status sooc_eval_table_miou_matched(const sooc_eval_table *t, const char *model, int scale, int is_query,
                                         int ref_scale, double *miou, double *coverage) {
    sooc_eval_cell c, r;
    *miou = NAN;
    if (coverage) *coverage = 0;
    if (sooc_eval_table_cell(t, model, scale, is_query, &c) || sooc_eval_table_cell(t, model, ref_scale, is_query, &r))
        return SOOC_ENOTFOUND;
    double num = 0, wsum = 0, wall = 0;
    for (int b = 0; b < SOOC_METRIC_N_OBINS; b++) {
        wall += (double)r.n_by_nobj[b];
        if (!r.n_by_nobj[b] || !c.n_by_nobj[b]) continue;
        num += (double)r.n_by_nobj[b] * c.miou_by_nobj[b];
        wsum += (double)r.n_by_nobj[b];
    }
    if (wsum <= 0) return SOOC_ENOTFOUND;
    *miou = num / wsum;
    if (coverage) *coverage = wsum / wall;
    return SOOC_OK;
}

/* ------------------------------------------------------------ string builder */

static sooc_status sb_finish(sooc_strbuf *b, char **out) {
    if (b->oom || !b->p) {
        sooc_free(b->p);
        return sooc_seterr(SOOC_ENOMEM, "eval table: out of memory formatting the table");
    }
    *out = b->p;
    return SOOC_OK;
}

/* models in insertion order, scales present */
static int list_models(const sooc_eval_table *t, const char **models, int cap) {
    int n = 0;
    for (int i = 0; i < t->n; i++) {
        int seen = 0;
        for (int j = 0; j < n; j++) seen |= !strcmp(models[j], t->e[i].model);
        if (!seen && n < cap) models[n++] = t->e[i].model;
    }
    return n;
}
static int scales_present(const sooc_eval_table *t, int *sc) {
    int n = 0;
    for (int s = 0; s < SOOC_N_SCALES; s++) {
        int any = 0;
        for (int i = 0; i < t->n; i++) any |= t->e[i].scale == s;
        if (any) sc[n++] = s;
    }
    return n;
}

static void fmt_stat(char *buf, size_t cap, const sooc_eval_stat *s, int dec) {
    if (!s->n_runs || !isfinite(s->mean)) snprintf(buf, cap, "-");
    else if (s->n_runs > 1) snprintf(buf, cap, "%.*f±%.*f", dec, s->mean, dec, s->std);
    else snprintf(buf, cap, "%.*f", dec, s->mean);
}

#define MAXM 64
enum { COL_MIOU, COL_RGB, COL_DEPTH, COL_L2, N_MAIN };
static const char *main_names[N_MAIN] = {"mIoU ↑", "RGB RMSE ↓", "depth RMSE ↓", "L2 (m) ↓"};

static const sooc_eval_stat *main_stat(const sooc_eval_cell *c, int col) {
    switch (col) {
    case COL_MIOU: return &c->miou_best;
    case COL_RGB: return &c->rgb_rmse;
    case COL_DEPTH: return &c->depth_rmse;
    default: return &c->l2;
    }
}

static void cell_text(const sooc_eval_table *t, const char *model, int sc, int q, int col, char *buf,
                      size_t cap) {
    sooc_eval_cell c;
    if (col == COL_L2 && !q && !t->l2_input) { snprintf(buf, cap, "n/a"); return; }
    if (sooc_eval_table_cell(t, model, sc, q, &c)) { snprintf(buf, cap, "-"); return; }
    fmt_stat(buf, cap, main_stat(&c, col), 3);
}

/* display width of UTF-8 text (count code points) */
static int dispw(const char *s) {
    int w = 0;
    for (; *s; s++) w += ((unsigned char)*s & 0xC0) != 0x80;
    return w;
}
static void sb_pad(sooc_strbuf *b, const char *s, int w, int right) {
    int pad = w - dispw(s);
    if (pad < 0) pad = 0;
    if (right) sooc_strbuf_printf(b, "%*s%s", pad, "", s);
    else sooc_strbuf_printf(b, "%s%*s", s, pad, "");
}

sooc_status sooc_eval_table_text(const sooc_eval_table *t, char **out) {
    sooc_strbuf b = {0};
    const char *models[MAXM];
    int sc[SOOC_N_SCALES];
    int nm = list_models(t, models, MAXM), ns = scales_present(t, sc);
    int mw = 5;
    for (int i = 0; i < nm; i++) if ((int)strlen(models[i]) > mw) mw = (int)strlen(models[i]);
    const int cw = 13;
    sb_pad(&b, "", mw + 5, 0);
    for (int c = 0; c < N_MAIN; c++) {
        sooc_strbuf_printf(&b, "| ");
        sb_pad(&b, main_names[c], ns * cw, 0);
    }
    sooc_strbuf_printf(&b, "\n");
    sb_pad(&b, "model", mw, 0);
    sooc_strbuf_printf(&b, "  IQ ");
    for (int c = 0; c < N_MAIN; c++) {
        sooc_strbuf_printf(&b, "| ");
        for (int s = 0; s < ns; s++) sb_pad(&b, sooc_scale_name(sc[s]), cw, 0);
    }
    sooc_strbuf_printf(&b, "\n");
    int total = mw + 5 + N_MAIN * (2 + ns * cw);
    for (int i = 0; i < total; i++) sooc_strbuf_printf(&b, "-");
    sooc_strbuf_printf(&b, "\n");
    for (int m = 0; m < nm; m++) {
        for (int q = 0; q < 2; q++) {
            sb_pad(&b, q ? "" : models[m], mw, 0);
            sooc_strbuf_printf(&b, "  %s  ", q ? "Q" : "I");
            for (int c = 0; c < N_MAIN; c++) {
                sooc_strbuf_printf(&b, "| ");
                for (int s = 0; s < ns; s++) {
                    char buf[64];
                    cell_text(t, models[m], sc[s], q, c, buf, sizeof buf);
                    sb_pad(&b, buf, cw, 0);
                }
            }
            sooc_strbuf_printf(&b, "\n");
        }
    }
    sooc_strbuf_printf(&b, "mIoU: MulMON best-match, background included; RGB RMSE: channel sum (docs/metrics.md); "
                  "mean±std over runs.\n");
    if (t->note) sooc_strbuf_printf(&b, "%s\n", t->note);
    return sb_finish(&b, out);
}

/* Supplementary table: mIoU by visible objects per view, and the
 * composition-matched mIoU against medium scenes when they were evaluated. */
static void md_by_nobj(sooc_strbuf *b, const sooc_eval_table *t, const char **models, int nm, const int *sc, int ns) {
    int have_m = 0;
    for (int s = 0; s < ns; s++) have_m |= sc[s] == SOOC_SCALE_M;
    sooc_strbuf_printf(b, "\nSupplementary: mIoU by the number of GT objects a view holds (views in brackets)%s.\n\n"
                 "| model | view | scale |", have_m ? "; composition-matched: the same, weighted as the medium "
                 "views are (docs/metrics.md)" : "");
    for (int k = 0; k < SOOC_METRIC_N_OBINS; k++)
        sooc_strbuf_printf(b, " %d%s |", k, k == SOOC_METRIC_N_OBINS - 1 ? "+" : "");
    sooc_strbuf_printf(b, "%s\n|---|---|---|", have_m ? " composition-matched |" : "");
    for (int k = 0; k < SOOC_METRIC_N_OBINS + have_m; k++) sooc_strbuf_printf(b, "---:|");
    sooc_strbuf_printf(b, "\n");
    for (int m = 0; m < nm; m++)
        for (int q = 0; q < 2; q++)
            for (int s = 0; s < ns; s++) {
                sooc_eval_cell c;
                if (sooc_eval_table_cell(t, models[m], sc[s], q, &c)) continue;
                sooc_strbuf_printf(b, "| %s | %s | %s |", models[m], q ? "Q" : "I", sooc_scale_name(sc[s]));
                for (int k = 0; k < SOOC_METRIC_N_OBINS; k++) {
                    if (c.n_by_nobj[k]) sooc_strbuf_printf(b, " %.3f (%ld) |", c.miou_by_nobj[k], c.n_by_nobj[k]);
                    else sooc_strbuf_printf(b, " - |");
                }
                double mm, cov;
                if (have_m && !sooc_eval_table_miou_matched(t, models[m], sc[s], q, SOOC_SCALE_M, &mm, &cov))
                    sooc_strbuf_printf(b, cov < 1 ? " %.3f (%.0f%% of m views) |" : " %.3f |", mm, 100 * cov);
                else if (have_m) sooc_strbuf_printf(b, " - |");
                sooc_strbuf_printf(b, "\n");
            }
}

sooc_status sooc_eval_table_markdown(const sooc_eval_table *t, char **out) {
    sooc_strbuf b = {0};
    const char *models[MAXM];
    int sc[SOOC_N_SCALES];
    int nm = list_models(t, models, MAXM), ns = scales_present(t, sc);
    sooc_strbuf_printf(&b, "| model | view |");
    for (int c = 0; c < N_MAIN; c++)
        for (int s = 0; s < ns; s++) sooc_strbuf_printf(&b, " %s %s |", main_names[c], sooc_scale_name(sc[s]));
    sooc_strbuf_printf(&b, "\n|---|---|");
    for (int i = 0; i < N_MAIN * ns; i++) sooc_strbuf_printf(&b, "---:|");
    sooc_strbuf_printf(&b, "\n");
    for (int m = 0; m < nm; m++)
        for (int q = 0; q < 2; q++) {
            sooc_strbuf_printf(&b, "| %s | %s |", q ? "" : models[m], q ? "Q" : "I");
            for (int c = 0; c < N_MAIN; c++)
                for (int s = 0; s < ns; s++) {
                    char buf[64];
                    cell_text(t, models[m], sc[s], q, c, buf, sizeof buf);
                    sooc_strbuf_printf(&b, " %s |", buf);
                }
            sooc_strbuf_printf(&b, "\n");
        }
    sooc_strbuf_printf(&b, "\nSupplementary: one-to-one (Hungarian) mIoU, fraction of visible GT objects matched, "
                  "recall by camera distance, RGB RMSE over object pixels (GT instance != 0).\n\n"
                  "| model | view | scale | views | mIoU Hungarian | matched | recall <3 m | recall 3-5 m | "
                  "recall >5 m | RGB RMSE objects |\n|---|---|---|---:|---:|---:|---:|---:|---:|---:|\n");
    for (int m = 0; m < nm; m++)
        for (int q = 0; q < 2; q++)
            for (int s = 0; s < ns; s++) {
                sooc_eval_cell c;
                if (sooc_eval_table_cell(t, models[m], sc[s], q, &c)) continue;
                char h[64], mf[64], r[3][64], ro[64];
                fmt_stat(h, sizeof h, &c.miou_hung, 3);
                fmt_stat(mf, sizeof mf, &c.matched_frac, 3);
                for (int k = 0; k < 3; k++) fmt_stat(r[k], sizeof r[k], &c.recall[k], 3);
                fmt_stat(ro, sizeof ro, &c.rgb_rmse_obj, 3);
                sooc_strbuf_printf(&b, "| %s | %s | %s | %ld | %s | %s | %s | %s | %s | %s |\n", models[m], q ? "Q" : "I",
                          sooc_scale_name(sc[s]), c.n_views, h, mf, r[0], r[1], r[2], ro);
            }
    md_by_nobj(&b, t, models, nm, sc, ns);
    sooc_strbuf_printf(&b, "\nmIoU: MulMON best-match per GT instance (background included, IoU < 0.05 -> 0); "
                  "RGB RMSE: sqrt of the per-pixel channel SUM of squared errors (divide by sqrt(3) for "
                  "the per-channel mean), over all pixels or (objects) GT instance != 0 only; depth RMSE in m "
                  "over GT depth <= d_clip; L2: floor-plane error of best-matched objects, query views. "
                  "Values: mean±std over runs. See docs/metrics.md.\n");
    if (t->note) sooc_strbuf_printf(&b, "\n%s\n", t->note);
    return sb_finish(&b, out);
}

static void json_num(sooc_strbuf *b, double v) {
    if (isfinite(v)) sooc_strbuf_printf(b, "%.6g", v);
    else sooc_strbuf_printf(b, "null");
}
static void json_stat(sooc_strbuf *b, const char *k, const sooc_eval_stat *s, int comma) {
    sooc_strbuf_printf(b, "\"%s\": {\"mean\": ", k);
    json_num(b, s->mean);
    sooc_strbuf_printf(b, ", \"std\": ");
    json_num(b, s->std);
    sooc_strbuf_printf(b, ", \"runs\": %d}%s", s->n_runs, comma ? ", " : "");
}
static void json_str(sooc_strbuf *b, const char *s) {
    sooc_strbuf_printf(b, "\"");
    for (; *s; s++) {
        unsigned char c = (unsigned char)*s;
        if (c == '"' || c == '\\') sooc_strbuf_printf(b, "\\%c", c);
        else if (c < 0x20) sooc_strbuf_printf(b, "\\u%04x", c);
        else sooc_strbuf_printf(b, "%c", c);
    }
    sooc_strbuf_printf(b, "\"");
}

sooc_status sooc_eval_table_json(const sooc_eval_table *t, char **out) {
    sooc_strbuf b = {0};
    const char *models[MAXM];
    int sc[SOOC_N_SCALES];
    int nm = list_models(t, models, MAXM), ns = scales_present(t, sc);
    sooc_strbuf_printf(&b, "{\"conventions\": {\"miou\": \"MulMON best-match, background included, IoU<0.05->0\", "
                  "\"rgb_rmse\": \"channel sum\", \"rgb_rmse_obj\": \"channel sum, GT instance != 0 pixels\", "
                  "\"depth_rmse\": \"m, GT depth <= d_clip\", "
                  "\"std\": \"sample std over runs\"}, ");
    sooc_strbuf_printf(&b, "\"note\": ");
    if (t->note) json_str(&b, t->note);
    else sooc_strbuf_printf(&b, "null");
    sooc_strbuf_printf(&b, ", \"cells\": [");
    int first = 1;
    for (int m = 0; m < nm; m++)
        for (int q = 0; q < 2; q++)
            for (int s = 0; s < ns; s++) {
                sooc_eval_cell c;
                if (sooc_eval_table_cell(t, models[m], sc[s], q, &c)) continue;
                sooc_strbuf_printf(&b, "%s\n  {\"model\": ", first ? "" : ",");
                first = 0;
                json_str(&b, models[m]);
                sooc_strbuf_printf(&b, ", \"scale\": \"%s\", \"view\": \"%s\", \"n_views\": %ld, ", sooc_scale_name(sc[s]),
                          q ? "Q" : "I", c.n_views);
                json_stat(&b, "miou", &c.miou_best, 1);
                json_stat(&b, "miou_hungarian", &c.miou_hung, 1);
                json_stat(&b, "rgb_rmse", &c.rgb_rmse, 1);
                json_stat(&b, "rgb_rmse_obj", &c.rgb_rmse_obj, 1);
                json_stat(&b, "depth_rmse", &c.depth_rmse, 1);
                json_stat(&b, "l2", &c.l2, 1);
                json_stat(&b, "matched_frac", &c.matched_frac, 1);
                json_stat(&b, "recall_lt3m", &c.recall[0], 1);
                json_stat(&b, "recall_3to5m", &c.recall[1], 1);
                json_stat(&b, "recall_gt5m", &c.recall[2], 1);
                json_stat(&b, "mesh_acc_cm", &c.mesh_acc_cm, 1);
                json_stat(&b, "mesh_comp_cm", &c.mesh_comp_cm, 1);
                json_stat(&b, "extent_err_cm", &c.extent_err_cm, 1);
                json_stat(&b, "sigma1_frac", &c.sigma1_frac, 1);
                json_stat(&b, "symmetric_agree", &c.symmetric_agree, 1);
                sooc_strbuf_printf(&b, "\"miou_by_nobj\": [");
                for (int k = 0; k < SOOC_METRIC_N_OBINS; k++) {
                    json_num(&b, c.miou_by_nobj[k]);
                    sooc_strbuf_printf(&b, k + 1 < SOOC_METRIC_N_OBINS ? ", " : "], \"views_by_nobj\": [");
                }
                for (int k = 0; k < SOOC_METRIC_N_OBINS; k++)
                    sooc_strbuf_printf(&b, "%ld%s", c.n_by_nobj[k], k + 1 < SOOC_METRIC_N_OBINS ? ", " : "]");
                double mm = NAN;
                sooc_eval_table_miou_matched(t, models[m], sc[s], q, SOOC_SCALE_M, &mm, NULL);
                sooc_strbuf_printf(&b, ", \"miou_composition_matched_m\": ");
                json_num(&b, mm);
                sooc_strbuf_printf(&b, "}");
            }
    sooc_strbuf_printf(&b, "\n]}\n");
    return sb_finish(&b, out);
}

sooc_status sooc_eval_table_write(const sooc_eval_table *t, const char *json_path, const char *md_path) {
    char *s = NULL;
    sooc_status st;
    if (json_path) {
        if ((st = sooc_eval_table_json(t, &s))) return st;
        st = sooc_file_write_atomic(json_path, s, strlen(s));
        sooc_free(s);
        if (st) return sooc_adderr(st, "eval table: %s", json_path);
    }
    if (md_path) {
        if ((st = sooc_eval_table_markdown(t, &s))) return st;
        st = sooc_file_write_atomic(md_path, s, strlen(s));
        sooc_free(s);
        if (st) return sooc_adderr(st, "eval table: %s", md_path);
    }
    return SOOC_OK;
}

sooc_status sooc_eval_view(const sooc_field *f, const double T_fc[16], const sooc_frame *gt,
                           const sooc_render_opts *ro, const double *pred_xz,
                           const sooc_gt_object *gt_obj, int n_gt_obj, sooc_render_out *out,
                           sooc_view_metrics *vm, sooc_iou_match *match) {
    if (!f || !gt || !out || !vm) return sooc_seterr(SOOC_EINVAL, "eval_view: missing argument");
    sooc_render_opts od;
    if (!ro) { sooc_render_opts_default(&od); ro = &od; }
    sooc_intrinsics K = gt->K;
    K.width = gt->width;
    K.height = gt->height;
    sooc_status st = sooc_render_view(f, &K, T_fc, ro, out);
    if (st) return sooc_adderr(st, "eval_view: frame %lld", (long long)gt->index);
    sooc_view_eval_in in = {gt, out, ro->d_clip, f->n_comp, pred_xz, gt_obj, n_gt_obj, NULL};
    st = sooc_metric_view(&in, vm, match);
    if (st) return sooc_adderr(st, "eval_view: frame %lld", (long long)gt->index);
    return SOOC_OK;
}
