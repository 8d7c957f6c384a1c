/* The evaluation metrics; definitions in docs/metrics.md. */
#include "sooc3d/eval.h"

#include <math.h>
#include <string.h>
#include <strings.h>

/* ---------------------------------------------------------------- Hungarian */

/* Shortest augmenting path (Kuhn-Munkres with potentials) for n <= m,
 * 1-based arrays; a[i][j] = cost(i-1, j-1). */
static sooc_status hungarian_le(const double *cost, int n, int m, int transposed, int *row_of_col_out) {
    size_t nn = (size_t)n + 1, mm = (size_t)m + 1;
    double *u = sooc_calloc(nn, sizeof(double)), *v = sooc_calloc(mm, sizeof(double));
    double *minv = sooc_malloc(mm * sizeof(double));
    int *p = sooc_calloc(mm, sizeof(int)), *way = sooc_calloc(mm, sizeof(int));
    char *used = sooc_malloc(mm);
    if (!u || !v || !minv || !p || !way || !used) {
        sooc_free(u); sooc_free(v); sooc_free(minv); sooc_free(p); sooc_free(way); sooc_free(used);
        return sooc_seterr(SOOC_ENOMEM, "hungarian: out of memory (%d x %d)", n, m);
    }
#define A(i, j) (transposed ? cost[(size_t)((j) - 1) * n + ((i) - 1)] : cost[(size_t)((i) - 1) * m + ((j) - 1)])
    for (int i = 1; i <= n; i++) {
        p[0] = i;
        int j0 = 0;
        for (int j = 0; j <= m; j++) { minv[j] = INFINITY; used[j] = 0; }
        do {
            used[j0] = 1;
            int i0 = p[j0], j1 = 0;
            double delta = INFINITY;
            for (int j = 1; j <= m; j++) {
                if (used[j]) continue;
                double cur = A(i0, j) - u[i0] - v[j];
                if (cur < minv[j]) { minv[j] = cur; way[j] = j0; }
                if (minv[j] < delta) { delta = minv[j]; j1 = j; }
            }
            if (j1 == 0) break;   /* cannot happen with finite costs */
            for (int j = 0; j <= m; j++) {
                if (used[j]) { u[p[j]] += delta; v[j] -= delta; }
                else minv[j] -= delta;
            }
            j0 = j1;
        } while (p[j0] != 0);
        do {
            int j1 = way[j0];
            p[j0] = p[j1];
            j0 = j1;
        } while (j0);
    }
#undef A
    for (int j = 1; j <= m; j++) row_of_col_out[j - 1] = p[j] - 1;   /* -1 = unassigned */
    sooc_free(u); sooc_free(v); sooc_free(minv); sooc_free(p); sooc_free(way); sooc_free(used);
    return SOOC_OK;
}

sooc_status sooc_hungarian(const double *cost, int n, int m, int *assign, double *total) {
    if (n < 0 || m < 0 || (n > 0 && m > 0 && !cost) || (n > 0 && !assign))
        return sooc_seterr(SOOC_EINVAL, "hungarian: bad arguments (%d x %d)", n, m);
    for (size_t i = 0; i < (size_t)n * m; i++)
        if (!isfinite(cost[i])) return sooc_seterr(SOOC_ENUMERIC, "hungarian: cost[%zu] not finite", i);
    for (int i = 0; i < n; i++) assign[i] = -1;
    if (total) *total = 0.0;
    if (n == 0 || m == 0) return SOOC_OK;
    if (n <= m) {
        int *rc = sooc_malloc((size_t)m * sizeof(int));
        if (!rc) return sooc_seterr(SOOC_ENOMEM, "hungarian: out of memory");
        sooc_status s = hungarian_le(cost, n, m, 0, rc);
        if (!s)
            for (int j = 0; j < m; j++)
                if (rc[j] >= 0) assign[rc[j]] = j;
        sooc_free(rc);
        if (s) return s;
    } else {
        /* transpose: rows = columns of cost (m <= n) */
        int *rc = sooc_malloc((size_t)n * sizeof(int));
        if (!rc) return sooc_seterr(SOOC_ENOMEM, "hungarian: out of memory");
        sooc_status s = hungarian_le(cost, m, n, 1, rc);
        if (!s)
            for (int i = 0; i < n; i++) assign[i] = rc[i];   /* rc[i] = column assigned to row i */
        sooc_free(rc);
        if (s) return s;
    }
    if (total) {
        double t = 0.0;
        for (int i = 0; i < n; i++)
            if (assign[i] >= 0) t += cost[(size_t)i * m + assign[i]];
        *total = t;
    }
    return SOOC_OK;
}

/* -------------------------------------------------------------------- mIoU */

sooc_status sooc_metric_miou(const int16_t *pred, int n_pred, const uint16_t *gt, const uint8_t *mask,
                             size_t n, sooc_iou_match *out) {
    memset(out, 0, sizeof *out);
    out->miou_best = out->miou_hung = NAN;
    if (n_pred < 0 || n_pred > SOOC_METRIC_MAX_PRED)
        return sooc_seterr(SOOC_EINVAL, "miou: n_pred = %d outside [0, %d]", n_pred, SOOC_METRIC_MAX_PRED);
    int32_t *slot = sooc_malloc(65536 * sizeof(int32_t));
    if (!slot) return sooc_seterr(SOOC_ENOMEM, "miou: out of memory");
    for (int i = 0; i < 65536; i++) slot[i] = -1;
    /* visible GT ids, ascending */
    uint8_t *seen = sooc_calloc(65536, 1);
    if (!seen) { sooc_free(slot); return sooc_seterr(SOOC_ENOMEM, "miou: out of memory"); }
    for (size_t p = 0; p < n; p++)
        if (!mask || mask[p]) seen[gt[p]] = 1;
    int ng = 0;
    for (int id = 0; id < 65536; id++) {
        if (!seen[id]) continue;
        if (ng >= SOOC_METRIC_MAX_GT) {
            sooc_free(slot); sooc_free(seen);
            return sooc_seterr(SOOC_EINVAL, "miou: more than %d visible GT instances", SOOC_METRIC_MAX_GT);
        }
        out->gt_id[ng] = (uint16_t)id;
        slot[id] = ng++;
    }
    sooc_free(seen);
    out->n_gt = ng;
    if (ng == 0) { sooc_free(slot); return SOOC_OK; }
    int np = n_pred > 0 ? n_pred : 1;
    long *inter = sooc_calloc((size_t)ng * np, sizeof(long));
    long *gcnt = sooc_calloc((size_t)ng, sizeof(long)), *pcnt = sooc_calloc((size_t)np, sizeof(long));
    double *iou = sooc_calloc((size_t)ng * np, sizeof(double));
    int *asg = sooc_malloc((size_t)ng * sizeof(int));
    sooc_status st = SOOC_OK;
    if (!inter || !gcnt || !pcnt || !iou || !asg) { st = sooc_seterr(SOOC_ENOMEM, "miou: out of memory"); goto done; }
    for (size_t p = 0; p < n; p++) {
        if (mask && !mask[p]) continue;
        int g = slot[gt[p]], k = pred[p];
        gcnt[g]++;
        if (k < 0) continue;   /* "none": only in the union */
        if (k >= n_pred) {
            st = sooc_seterr(SOOC_EINVAL, "miou: predicted label %d at pixel %zu >= n_pred %d", k, p, n_pred);
            goto done;
        }
        pcnt[k]++;
        inter[(size_t)g * np + k]++;
    }
    double sb = 0.0, sh = 0.0;
    for (int g = 0; g < ng; g++) {
        double best = 0.0;
        int bk = -1;
        for (int k = 0; k < n_pred; k++) {
            long in = inter[(size_t)g * np + k], un = gcnt[g] + pcnt[k] - in;
            double v = un > 0 ? (double)in / (double)un : 0.0;
            iou[(size_t)g * np + k] = v;
            if (v > best) { best = v; bk = k; }
        }
        if (best < SOOC_METRIC_IOU_MIN) { best = 0.0; bk = -1; }
        out->best_iou[g] = best;
        out->best_pred[g] = bk;
        sb += best;
    }
    if (n_pred > 0) {
        for (size_t i = 0; i < (size_t)ng * np; i++) iou[i] = -iou[i];
        st = sooc_hungarian(iou, ng, n_pred, asg, NULL);
        if (st) goto done;
    } else {
        for (int g = 0; g < ng; g++) asg[g] = -1;
    }
    for (int g = 0; g < ng; g++) {
        double v = asg[g] >= 0 ? -iou[(size_t)g * np + asg[g]] : 0.0;
        if (v < SOOC_METRIC_IOU_MIN) { v = 0.0; asg[g] = -1; }
        out->hung_iou[g] = v;
        out->hung_pred[g] = asg[g];
        sh += v;
    }
    out->miou_best = sb / ng;
    out->miou_hung = sh / ng;
done:
    sooc_free(slot); sooc_free(inter); sooc_free(gcnt); sooc_free(pcnt); sooc_free(iou); sooc_free(asg);
    return st;
}

/* --------------------------------------------------------------------- RMSE */

size_t sooc_metric_valid_mask(const float *gt_depth, const uint8_t *valid, size_t n, double d_clip,
                              uint8_t *mask) {
    size_t c = 0;
    for (size_t p = 0; p < n; p++) {
        float d = gt_depth[p];
        int ok = (!valid || valid[p]) && isfinite(d) && d > 0.f && d <= d_clip;
        mask[p] = (uint8_t)ok;
        c += (size_t)ok;
    }
    return c;
}

double sooc_metric_rgb_rmse(const float *pred, const uint8_t *gt, const uint8_t *mask, size_t n) {
    double s = 0.0;
    size_t c = 0;
    for (size_t p = 0; p < n; p++) {
        if (mask && !mask[p]) continue;
        for (int ch = 0; ch < 3; ch++) {
            double d = (double)pred[3 * p + ch] - gt[3 * p + ch] / 255.0;
            s += d * d;
        }
        c++;
    }
    return c ? sqrt(s / (double)c) : NAN;
}

double sooc_metric_depth_rmse(const float *pred, const float *gt, const uint8_t *mask, size_t n) {
    double s = 0.0;
    size_t c = 0;
    for (size_t p = 0; p < n; p++) {
        if (mask && !mask[p]) continue;
        double d = (double)pred[p] - gt[p];
        s += d * d;
        c++;
    }
    return c ? sqrt(s / (double)c) : NAN;
}

/* ------------------------------------------------------------ per-view bundle */

static int dist_bin(double d) { return d < 3.0 ? 0 : d < 5.0 ? 1 : 2; }

sooc_status sooc_metric_view(const sooc_view_eval_in *in, sooc_view_metrics *out,
                             sooc_iou_match *match_out) {
    memset(out, 0, sizeof *out);
    out->miou_best = out->miou_hung = out->rgb_rmse = out->depth_rmse = out->rgb_rmse_obj = NAN;
    const sooc_frame *g = in->gt;
    const sooc_render_out *pr = in->pred;
    if (!g || !pr || !g->depth || !g->rgb || !pr->rgb || !pr->depth || !pr->label)
        return sooc_seterr(SOOC_EINVAL, "metric_view: missing ground truth or prediction buffers");
    if (g->width != pr->width || g->height != pr->height)
        return sooc_seterr(SOOC_EINVAL, "metric_view: GT %dx%d vs prediction %dx%d", g->width,
                           g->height, pr->width, pr->height);
    out->is_query = g->is_query;
    size_t n = (size_t)g->width * g->height;
    uint8_t *mask = in->mask_scratch;
    if (!mask && !(mask = sooc_malloc(n))) return sooc_seterr(SOOC_ENOMEM, "metric_view: out of memory");
    out->n_valid_pixels = sooc_metric_valid_mask(g->depth, g->valid, n, in->d_clip, mask);
    out->rgb_rmse = sooc_metric_rgb_rmse(pr->rgb, g->rgb, mask, n);
    out->depth_rmse = sooc_metric_depth_rmse(pr->depth, g->depth, mask, n);
    sooc_status st = SOOC_OK;
    sooc_iou_match local, *m = match_out ? match_out : &local;
    memset(m, 0, sizeof *m);
    if (g->instance) {
        st = sooc_metric_miou(pr->label, in->n_pred, g->instance, mask, n, m);
        if (st) goto done;
        out->miou_best = m->miou_best;
        out->miou_hung = m->miou_hung;
        out->n_gt_visible = m->n_gt;
        double cx = g->T_wc[3], cz = g->T_wc[11];
        for (int i = 0; i < m->n_gt; i++) {
            if (m->gt_id[i] == 0) continue;
            const sooc_gt_object *o = NULL;
            for (int j = 0; j < in->n_gt_obj; j++)
                if (in->gt_obj[j].id == m->gt_id[i]) { o = &in->gt_obj[j]; break; }
            if (!o) continue;
            int b = dist_bin(hypot(o->x - cx, o->z - cz));
            out->n_obj_visible++;
            out->recall_tot[b]++;
            int k = m->best_pred[i];
            if (k < 0 || !in->pred_xz) continue;
            double px = in->pred_xz[2 * k], pz = in->pred_xz[2 * k + 1];
            if (!isfinite(px) || !isfinite(pz)) continue;
            out->n_obj_matched++;
            out->recall_hit[b]++;
            out->l2_sum += hypot(px - o->x, pz - o->z);
        }
        /* object pixels: narrow M in place to GT id != 0 (M is not needed after this) */
        for (size_t p = 0; p < n; p++) mask[p] &= (uint8_t)(g->instance[p] != 0);
        out->rgb_rmse_obj = sooc_metric_rgb_rmse(pr->rgb, g->rgb, mask, n);
    }
done:
    if (mask != in->mask_scratch) sooc_free(mask);
    return st;
}

/* ------------------------------------------------------------- accumulation */

int sooc_scale_parse(const char *s) {
    if (!s) return -1;
    if (!strcasecmp(s, "s") || !strcasecmp(s, "small")) return SOOC_SCALE_S;
    if (!strcasecmp(s, "m") || !strcasecmp(s, "medium")) return SOOC_SCALE_M;
    if (!strcasecmp(s, "l") || !strcasecmp(s, "large")) return SOOC_SCALE_L;
    if (!strcasecmp(s, "xl") || !strcasecmp(s, "xlarge")) return SOOC_SCALE_XL;
    return -1;
}

const char *sooc_scale_name(int scale) {
    static const char *n[] = {"s", "m", "l", "xl"};
    return scale >= 0 && scale < SOOC_N_SCALES ? n[scale] : "?";
}

void sooc_metric_sums_add_view(sooc_metric_sums *s, const sooc_view_metrics *v) {
    s->n_views++;
    if (isfinite(v->miou_best)) {
        s->miou_best += v->miou_best;
        s->miou_hung += v->miou_hung;
        s->n_miou++;
        int b = v->n_obj_visible < SOOC_METRIC_N_OBINS - 1 ? v->n_obj_visible : SOOC_METRIC_N_OBINS - 1;
        s->miou_by_nobj[b] += v->miou_best;
        s->n_by_nobj[b]++;
    }
    if (isfinite(v->rgb_rmse)) { s->rgb_rmse += v->rgb_rmse; s->n_rgb++; }
    if (isfinite(v->rgb_rmse_obj)) { s->rgb_rmse_obj += v->rgb_rmse_obj; s->n_rgb_obj++; }
    if (isfinite(v->depth_rmse)) { s->depth_rmse += v->depth_rmse; s->n_depth++; }
    s->l2_sum += v->l2_sum;
    s->n_obj_matched += v->n_obj_matched;
    s->n_obj_visible += v->n_obj_visible;
    for (int b = 0; b < SOOC_METRIC_N_DBINS; b++) {
        s->recall_hit[b] += v->recall_hit[b];
        s->recall_tot[b] += v->recall_tot[b];
    }
}

void sooc_metric_sums_merge(sooc_metric_sums *d, const sooc_metric_sums *s) {
    d->n_views += s->n_views;
    d->miou_best += s->miou_best; d->miou_hung += s->miou_hung; d->n_miou += s->n_miou;
    d->rgb_rmse += s->rgb_rmse; d->n_rgb += s->n_rgb;
    d->rgb_rmse_obj += s->rgb_rmse_obj; d->n_rgb_obj += s->n_rgb_obj;
    d->depth_rmse += s->depth_rmse; d->n_depth += s->n_depth;
    d->l2_sum += s->l2_sum; d->n_obj_matched += s->n_obj_matched; d->n_obj_visible += s->n_obj_visible;
    for (int b = 0; b < SOOC_METRIC_N_DBINS; b++) {
        d->recall_hit[b] += s->recall_hit[b];
        d->recall_tot[b] += s->recall_tot[b];
    }
    for (int b = 0; b < SOOC_METRIC_N_OBINS; b++) {
        d->miou_by_nobj[b] += s->miou_by_nobj[b];
        d->n_by_nobj[b] += s->n_by_nobj[b];
    }
    d->mesh.n_obj += s->mesh.n_obj;
    d->mesh.acc_cm += s->mesh.acc_cm;
    d->mesh.comp_cm += s->mesh.comp_cm;
    d->mesh.fscore += s->mesh.fscore;
    for (int b = 0; b < SOOC_METRIC_EXT_BINS; b++) d->geom.ext_hist[b] += s->geom.ext_hist[b];
    d->geom.n_ext += s->geom.n_ext;
    d->geom.n_axis += s->geom.n_axis;
    d->geom.n_axis_within += s->geom.n_axis_within;
    d->geom.n_sym += s->geom.n_sym;
    d->geom.n_sym_agree += s->geom.n_sym_agree;
}

void sooc_geom_sums_add_extent(sooc_geom_sums *g, double err_cm) {
    if (!isfinite(err_cm) || err_cm < 0) return;
    double b = err_cm / SOOC_METRIC_EXT_BIN_CM;
    g->ext_hist[b < SOOC_METRIC_EXT_BINS - 1 ? (int)b : SOOC_METRIC_EXT_BINS - 1]++;
    g->n_ext++;
}

/* the median of the histogram, linear within its bin */
static double geom_median(const sooc_geom_sums *g) {
    if (g->n_ext <= 0) return NAN;
    double half = 0.5 * (double)g->n_ext, c = 0;
    for (int b = 0; b < SOOC_METRIC_EXT_BINS; b++) {
        if (!g->ext_hist[b]) continue;
        if (c + (double)g->ext_hist[b] >= half)
            return SOOC_METRIC_EXT_BIN_CM * (b + (half - c) / (double)g->ext_hist[b]);
        c += (double)g->ext_hist[b];
    }
    return SOOC_METRIC_EXT_BIN_CM * SOOC_METRIC_EXT_BINS;
}

static double ratio(double a, long n) { return n > 0 ? a / (double)n : NAN; }

void sooc_metric_sums_means(const sooc_metric_sums *s, sooc_metric_means *m) {
    m->n_views = s->n_views;
    m->miou_best = ratio(s->miou_best, s->n_miou);
    m->miou_hung = ratio(s->miou_hung, s->n_miou);
    m->rgb_rmse = ratio(s->rgb_rmse, s->n_rgb);
    m->rgb_rmse_obj = ratio(s->rgb_rmse_obj, s->n_rgb_obj);
    m->depth_rmse = ratio(s->depth_rmse, s->n_depth);
    m->l2 = ratio(s->l2_sum, s->n_obj_matched);
    m->matched_frac = ratio((double)s->n_obj_matched, s->n_obj_visible);
    for (int b = 0; b < SOOC_METRIC_N_DBINS; b++) m->recall[b] = ratio((double)s->recall_hit[b], s->recall_tot[b]);
    for (int b = 0; b < SOOC_METRIC_N_OBINS; b++) {
        m->miou_by_nobj[b] = ratio(s->miou_by_nobj[b], s->n_by_nobj[b]);
        m->n_by_nobj[b] = s->n_by_nobj[b];
    }
    m->mesh_acc_cm = ratio(s->mesh.acc_cm, s->mesh.n_obj);
    m->mesh_comp_cm = ratio(s->mesh.comp_cm, s->mesh.n_obj);
    m->mesh_fscore = ratio(s->mesh.fscore, s->mesh.n_obj);
    m->extent_err_cm = geom_median(&s->geom);
    m->sigma1_frac = ratio((double)s->geom.n_axis_within, s->geom.n_axis);
    m->symmetric_agree = ratio((double)s->geom.n_sym_agree, s->geom.n_sym);
}

void sooc_metric_acc_add_view(sooc_metric_acc *a, int scale, const sooc_view_metrics *v) {
    if (scale < 0 || scale >= SOOC_N_SCALES) return;
    sooc_metric_sums_add_view(&a->cell[scale][v->is_query ? 1 : 0], v);
}
