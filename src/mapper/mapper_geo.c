/* The geometric object map behind the mapper's interface (docs/geometric.md
 * "In the node"): every keyframe goes into one support-plane cluster map
 * (mapper.h); after it, the map's clusters are matched to the entries by
 * floor position (nearest first, within the larger of the two floor
 * half-diagonals plus match_m). A matched entry takes the cluster's box; a
 * cluster without an entry becomes one; an entry whose centre is in the
 * keyframe's view that no cluster continues is removed (out of view, an
 * entry stays: a resumed map, or the far end of a large scene). The change
 * set of one update holds at most SOOC_MAPPER_CHANGED_MAX entries and as many
 * removals; the rest wait for the next updates (oldest change first). */
#include "mapper/mapper_geo.h"
#include "sooc3d/mapper.h"
#include "sooc3d/core.h"

#include <math.h>
#include <string.h>

#define GEO_MATCH_M 0.03     /* match distance beyond the half-diagonals (m)        */
#define GEO_MOVED_M 0.003    /* a box that moves or grows less than this is unchanged */
#define GEO_PRES_MOVED 0.05  /* a presence change that republishes the entry          */
#define GEO_SIGMA_MOVED 0.1  /* a relative change of the position sigma that does     */

typedef struct geo_entry {
    sooc_map_entry e;
    uint64_t dirty;          /* 0 = published; else the update that changed it (oldest first) */
    sooc_map_entry pub;      /* the entry as last published (what the table and the store hold) */
    uint32_t n_in, n_whole;  /* keyframes that saw its box's centre; of them, those that saw the whole box */
    int shown;               /* in the entries and changes (presence reached min_presence) */
} geo_entry;

struct sooc_mdl_geo {
    sooc_cluster_params cp;
    double min_pres;         /* the presence an entry needs to be shown (mapper.h min_presence) */
    sooc_cluster_map *cm;
    int w, h;
    geo_entry *ent;
    size_t n, cap;
    uint64_t next_id, upd;
    uint64_t *rem;           /* removals not yet reported */
    size_t n_rem, cap_rem;
    sooc_cluster_object *obj;
    int obj_cap;
    uint64_t chg[SOOC_MAPPER_CHANGED_MAX], rep_rem[SOOC_MAPPER_CHANGED_MAX];
    size_t n_chg, n_rep_rem;
};

sooc_status sooc_mdl_geo_create(sooc_mdl_geo **out, const sooc_mapper_params *p) {
    *out = NULL;
    if (p->input_width < 8 || p->input_height < 8 || p->input_width > 8192 || p->input_height > 8192)
        return sooc_seterr(SOOC_EINVAL, "mapper (geometric): input size %dx%d (8..8192)", p->input_width,
                           p->input_height);
    sooc_mdl_geo *g = sooc_calloc(1, sizeof *g);
    if (!g) return sooc_seterr(SOOC_ENOMEM, "mapper (geometric): out of memory");
    if (!(p->min_presence >= 0 && p->min_presence <= 1)) {
        sooc_free(g);
        return sooc_seterr(SOOC_EINVAL, "mapper (geometric): min_presence %g (0..1)", p->min_presence);
    }
    g->cp = p->cluster;
    g->min_pres = p->min_presence;
    g->w = p->input_width, g->h = p->input_height;
    g->next_id = 1;
    sooc_status st = sooc_cluster_map_create(&g->cm, &g->cp);
    if (st) {
        sooc_free(g);
        return sooc_adderr(st, "mapper (geometric)");
    }
    *out = g;
    return SOOC_OK;
}

void sooc_mdl_geo_destroy(sooc_mdl_geo *g) {
    if (!g) return;
    sooc_cluster_map_destroy(g->cm);
    sooc_free(g->ent);
    sooc_free(g->rem);
    sooc_free(g->obj);
    sooc_free(g);
}

void sooc_mdl_geo_input_size(const sooc_mdl_geo *g, int *w, int *h) { *w = g->w, *h = g->h; }
void sooc_mdl_geo_clear(sooc_mdl_geo *g) {
    sooc_cluster_map_clear(g->cm);
    g->n = g->n_rem = 0;
    g->n_chg = g->n_rep_rem = 0;
}

uint64_t sooc_mdl_geo_next_id(const sooc_mdl_geo *g) { return g->next_id; }
void sooc_mdl_geo_reserve_ids(sooc_mdl_geo *g, uint64_t next_id) {
    if (next_id > g->next_id) g->next_id = next_id;
}

static sooc_status grow(void **p, size_t *cap, size_t need, size_t sz) {
    if (need <= *cap) return SOOC_OK;
    size_t c = *cap ? *cap : 64;
    while (c < need) c *= 2;
    void *q = sooc_realloc(*p, c * sz);
    if (!q) return sooc_seterr(SOOC_ENOMEM, "mapper (geometric): out of memory for %zu entries", c);
    *p = q, *cap = c;
    return SOOC_OK;
}

/* the entry's centre is in the keyframe's image, in front of the camera, within the depth range */
static int in_view(const sooc_frame *f, const sooc_map_entry *e, double max_depth) {
    double T[16], w[3] = {e->x, e->geom.centre[1], e->z}, c[3];
    sooc_se3_inverse(T, f->T_wc);
    sooc_se3_apply(c, T, w);
    if (!(c[2] > 0.05) || c[2] > max_depth) return 0;
    double u = f->K.fx * c[0] / c[2] + f->K.cx, v = f->K.fy * c[1] / c[2] + f->K.cy;
    return u >= 0 && v >= 0 && u < f->width && v < f->height;
}

/* Where a box lies in a keyframe's image: 0 its centre is not in view, 1 the centre is, 2 all its corners
 * are (in front of the camera, inside the image). */
static int box_view(const sooc_frame *f, const sooc_map_entry *e, double max_depth) {
    if (!in_view(f, e, max_depth)) return 0;
    double T[16], c = cos(e->yaw), s = sin(e->yaw);
    sooc_se3_inverse(T, f->T_wc);
    for (int k = 0; k < 8; k++) {
        double bx = (k & 1 ? 0.5 : -0.5) * e->extent[0], by = (k & 2 ? 0.5 : -0.5) * e->extent[1],
               bz = (k & 4 ? 0.5 : -0.5) * e->extent[2];
        /* the box's x axis in the world is (cos yaw, 0, -sin yaw), its z axis (sin yaw, 0, cos yaw) */
        double w[3] = {e->x + c * bx + s * bz, e->geom.centre[1] + by, e->z - s * bx + c * bz}, q[3];
        sooc_se3_apply(q, T, w);
        if (!(q[2] > 0.05)) return 1;
        double u = f->K.fx * q[0] / q[2] + f->K.cx, v = f->K.fy * q[1] / q[2] + f->K.cy;
        if (!(u >= 0 && v >= 0 && u < f->width && v < f->height)) return 1;
    }
    return 2;
}

/* Presence: how often the keyframes that saw the entry's centre saw its whole box, (whole + 1) / (in + 2).
 * A cluster that always runs out of the image (a wall, a bin's side, the surround) stays near 0.5 or below;
 * an object seen whole goes to 1 (docs/shm.md "The geometric map's fields"). */
static void take_presence(geo_entry *ge, const sooc_frame *f, double max_depth) {
    int v = box_view(f, &ge->e, max_depth);
    if (v) ge->n_in++;
    if (v == 2) ge->n_whole++;
    sooc_map_entry *e = &ge->e;
    float p = (float)(ge->n_whole + 1) / (float)(ge->n_in + 2);
    e->presence = p;
    e->presence_logit = logf(p / (1.0f - p));
}

/* The entry differs from what was last published by more than the republish tolerances: its box moved or
 * grew by 3 mm or turned by 0.02 rad, its presence changed by 0.05, its position sigma by 10%, or it stopped
 * being tentative (fewer than 2 observations). Slow changes add up against the published values. */
static int drifted(const geo_entry *ge) {
    const sooc_map_entry *e = &ge->e, *q = &ge->pub;
    int moved = fabs(e->x - q->x) > GEO_MOVED_M || fabs(e->z - q->z) > GEO_MOVED_M ||
                fabs(sooc_wrap_angle(e->yaw - q->yaw)) > 0.02;
    for (int i = 0; i < 3; i++) moved |= fabs(e->extent[i] - q->extent[i]) > GEO_MOVED_M;
    moved |= fabsf(e->presence - q->presence) > GEO_PRES_MOVED;
    moved |= fabs(e->sigma_t - q->sigma_t) > GEO_SIGMA_MOVED * q->sigma_t;
    moved |= (e->obs_count < 2) != (q->obs_count < 2);
    return moved;
}

/* An entry from a cluster: box, pose, colour as the latent; the registration
 * statistics (Welford) over the updates that matched it. */
static void take_cluster(geo_entry *ge, const sooc_cluster_object *o, const sooc_frame *f, double voxel) {
    sooc_map_entry *e = &ge->e;
    e->x = o->x, e->z = o->z, e->yaw = o->yaw;
    for (int i = 0; i < 3; i++) e->extent[i] = (float)o->extent[i];
    e->latent_dim = SOOC_GEOMETRIC_LATENT_DIM;
    for (int i = 0; i < 3; i++) e->what_mu[i] = (float)o->rgb[i], e->what_logvar[i] = 0;
    if (!e->obs_count) e->first_seen_ns = f->t_ns;
    e->last_seen_ns = f->t_ns;
    e->obs_count++;
    sooc_map_geometry *g = &e->geom;
    g->flags = SOOC_GEOM_TIGHT;
    g->centre[0] = g->centre[2] = 0;
    g->centre[1] = (float)o->centre_y;
    g->sym_iou = 0;
    /* spread of the registered floor positions and headings (Welford; headings mod pi / 2, a box's symmetry) */
    g->reg_n++;
    double dx = e->x - g->reg_mean[0], dz = e->z - g->reg_mean[1];
    g->reg_mean[0] += dx / g->reg_n, g->reg_mean[1] += dz / g->reg_n;
    g->reg_m2[0] += dx * (e->x - g->reg_mean[0]);
    g->reg_m2[1] += dx * (e->z - g->reg_mean[1]);
    g->reg_m2[2] += dz * (e->z - g->reg_mean[1]);
    g->reg_cs[0] += cos(4 * e->yaw), g->reg_cs[1] += sin(4 * e->yaw);
    /* Where the object's centre is: the mean of the registrations, whose variance is their spread / n (it
     * shrinks with evidence and grows with disagreement), at least half a voxel; plus where in the box
     * the centre lies. A cluster's box is its visible surface's, and touching objects share one
     * cluster, so an object's centre is taken uniform over the box's footprint (variance extent^2 / 12
     * along each box axis, turned into the map's axes). */
    double v0 = 0.25 * voxel * voxel, n = (double)g->reg_n;
    double bx = o->extent[0] * o->extent[0] / 12.0, bz = o->extent[2] * o->extent[2] / 12.0;
    double cy = cos(e->yaw), sy = sin(e->yaw);
    g->cov_xz[0] = fmax(g->reg_m2[0] / (n * n), v0) + cy * cy * bx + sy * sy * bz;
    g->cov_xz[1] = g->reg_m2[1] / (n * n) + cy * sy * (bz - bx);
    g->cov_xz[2] = fmax(g->reg_m2[2] / (n * n), v0) + sy * sy * bx + cy * cy * bz;
    e->sigma_t = sqrt(0.5 * (g->cov_xz[0] + g->cov_xz[2]));
    double r = hypot(g->reg_cs[0], g->reg_cs[1]) / n;
    double sd = r < 1 ? sqrt(-2.0 * log(r > 1e-12 ? r : 1e-12)) / 4 : 0;   /* circular std of 4 yaw, / 4 */
    /* at least half the 1 degree search step, at most the std of a heading uniform over 90 degrees */
    e->sigma_yaw = fmin(fmax(sd, 0.5 * M_PI / 180.0), 0.5 * M_PI / sqrt(12.0));
    g->var_yaw = e->sigma_yaw * e->sigma_yaw;
}

/* An entry the table and the store hold leaves them with the next change sets. */
static sooc_status report_removed(sooc_mdl_geo *g, uint64_t id) {
    sooc_status st = grow((void **)&g->rem, &g->cap_rem, g->n_rem + 1, sizeof *g->rem);
    if (!st) g->rem[g->n_rem++] = id;
    return st;
}

sooc_status sooc_mdl_geo_update(sooc_mdl_geo *g, const sooc_frame *f, sooc_update_stats *us) {
    double t0 = sooc_seconds();
    memset(us, 0, sizeof *us);
    g->upd++;
    int n = 0;
    sooc_status st = sooc_cluster_map_add_frame(g->cm, f);
    if (!st) st = sooc_cluster_map_segment(g->cm, &n);
    if (!st && n > g->obj_cap) {
        sooc_cluster_object *o = sooc_realloc(g->obj, (size_t)n * sizeof *o);
        if (!o) st = sooc_seterr(SOOC_ENOMEM, "mapper (geometric): out of memory for %d objects", n);
        else g->obj = o, g->obj_cap = n;
    }
    if (!st) st = sooc_cluster_map_objects(g->cm, g->obj, n, &n);
    if (!st) st = grow((void **)&g->ent, &g->cap, g->n + (size_t)n, sizeof *g->ent);
    if (st) return sooc_adderr(st, "mapper (geometric): frame %lld", (long long)f->index);
    /* match clusters to entries, nearest pairs first (n and the entries are small) */
    size_t ne0 = g->n;
    uint8_t used_e[4096], *ue = ne0 <= sizeof used_e ? used_e : sooc_calloc(ne0, 1);
    if (!ue) return sooc_seterr(SOOC_ENOMEM, "mapper (geometric): out of memory");
    memset(ue, 0, ne0 <= sizeof used_e ? ne0 : 0);
    for (int i = 0; i < n; i++) {
        const sooc_cluster_object *o = &g->obj[i];
        double ho = 0.5 * hypot(o->extent[0], o->extent[2]), best = INFINITY;
        size_t bj = (size_t)-1;
        for (size_t j = 0; j < ne0; j++) {
            if (ue[j]) continue;
            const sooc_map_entry *e = &g->ent[j].e;
            double d = hypot(e->x - o->x, e->z - o->z);
            double reach = fmax(ho, 0.5 * hypot(e->extent[0], e->extent[2])) + GEO_MATCH_M;
            if (d < reach && d < best) best = d, bj = j;
        }
        if (bj != (size_t)-1) {
            ue[bj] = 1;
            us->n_registered++;
            take_cluster(&g->ent[bj], o, f, g->cp.voxel_m);
            take_presence(&g->ent[bj], f, g->cp.max_depth_m);
        } else {
            geo_entry *ge = &g->ent[g->n++];
            memset(ge, 0, sizeof *ge);
            ge->e.id = g->next_id++;
            ge->dirty = g->upd;
            take_cluster(ge, o, f, g->cp.voxel_m);
            take_presence(ge, f, g->cp.max_depth_m);
            us->n_registered++, us->n_new++;
        }
    }
    /* entries in view that no cluster continues */
    size_t k = 0;
    for (size_t j = 0; j < g->n && !st; j++) {
        int keep = j >= ne0 || ue[j] || !in_view(f, &g->ent[j].e, g->cp.max_depth_m);
        if (keep) {
            g->ent[k++] = g->ent[j];
            continue;
        }
        if (g->ent[j].shown && (st = report_removed(g, g->ent[j].e.id))) break;
        us->n_removed++;
    }
    if (ue != used_e) sooc_free(ue);
    if (st) return st;
    g->n = k;
    /* the presence gate: shown from min_presence on, withdrawn below it less the hysteresis */
    for (size_t j = 0; j < g->n && !st; j++) {
        geo_entry *ge = &g->ent[j];
        if (!ge->shown && ge->e.presence >= g->min_pres) {
            ge->shown = 1;
            ge->dirty = g->upd;
            size_t kept = 0;   /* a withdrawal not yet reported is void */
            for (size_t r = 0; r < g->n_rem; r++)
                if (g->rem[r] != ge->e.id) g->rem[kept++] = g->rem[r];
            g->n_rem = kept;
        } else if (ge->shown && ge->e.presence < g->min_pres - SOOC_MAPPER_PRESENCE_HYST) {
            ge->shown = 0;
            ge->dirty = 0;
            st = report_removed(g, ge->e.id);
        } else if (ge->shown && !ge->dirty && drifted(ge)) {
            ge->dirty = g->upd;
        }
    }
    if (st) return st;
    /* this update's change set: the oldest changes first */
    g->n_chg = 0;
    for (;;) {
        size_t bj = (size_t)-1;
        for (size_t j = 0; j < g->n; j++)
            if (g->ent[j].shown && g->ent[j].dirty && (bj == (size_t)-1 || g->ent[j].dirty < g->ent[bj].dirty))
                bj = j;
        if (bj == (size_t)-1 || g->n_chg == SOOC_MAPPER_CHANGED_MAX) break;
        g->chg[g->n_chg++] = g->ent[bj].e.id;
        g->ent[bj].dirty = 0;
        g->ent[bj].pub = g->ent[bj].e;
    }
    g->n_rep_rem = g->n_rem < SOOC_MAPPER_CHANGED_MAX ? g->n_rem : SOOC_MAPPER_CHANGED_MAX;
    if (g->n_rep_rem) {
        memcpy(g->rep_rem, g->rem, g->n_rep_rem * sizeof *g->rem);
        memmove(g->rem, g->rem + g->n_rep_rem, (g->n_rem - g->n_rep_rem) * sizeof *g->rem);
        g->n_rem -= g->n_rep_rem;
    }
    us->elapsed_ms = 1e3 * (sooc_seconds() - t0);
    return SOOC_OK;
}

sooc_status sooc_mdl_geo_entries(const sooc_mdl_geo *g, sooc_map_entry *out, size_t cap, size_t *n) {
    size_t k = 0;
    for (size_t i = 0; i < g->n; i++) {
        if (!g->ent[i].shown) continue;
        if (out && k < cap) out[k] = g->ent[i].e;
        k++;
    }
    *n = out && k > cap ? cap : k;
    return SOOC_OK;
}

sooc_status sooc_mdl_geo_load_entries(sooc_mdl_geo *g, const sooc_map_entry *e, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (e[i].latent_dim != SOOC_GEOMETRIC_LATENT_DIM || !e[i].id)
            return sooc_seterr(SOOC_EINVAL, "mapper (geometric): entry %llu has latent_dim %d, a geometric map's "
                                            "entries have %d (a map made by a learnt model?)",
                               (unsigned long long)e[i].id, e[i].latent_dim, SOOC_GEOMETRIC_LATENT_DIM);
    g->n = 0;
    sooc_status st = grow((void **)&g->ent, &g->cap, n, sizeof *g->ent);
    if (st) return st;
    for (size_t i = 0; i < n; i++) {
        memset(&g->ent[i], 0, sizeof g->ent[i]);
        g->ent[i].e = e[i];
        g->ent[i].shown = 1;   /* it was stored, so it was shown */
        g->ent[i].pub = e[i];
        /* the presence's counts taken back from what was stored: its keyframes in view about its
         * observations, of them seen whole as many as give its presence ((whole + 1) / (in + 2)) */
        double in = e[i].obs_count < 100000u ? (double)e[i].obs_count : 100000.0;
        double whole = floor(e[i].presence * (in + 2.0) - 1.0 + 0.5);
        if (!(whole >= 0)) whole = 0;
        if (whole > in) whole = in;
        g->ent[i].n_in = (uint32_t)in, g->ent[i].n_whole = (uint32_t)whole;
        if (e[i].id >= g->next_id) g->next_id = e[i].id + 1;
    }
    g->n = n;
    g->n_chg = g->n_rep_rem = g->n_rem = 0;
    return SOOC_OK;
}

sooc_status sooc_mdl_geo_changed(const sooc_mdl_geo *g, sooc_map_entry *out, size_t cap, size_t *n, uint64_t *removed_ids,
                            size_t cap_r, size_t *n_removed) {
    if (n) *n = g->n_chg;
    if (n_removed) *n_removed = g->n_rep_rem;
    if ((out && g->n_chg > cap) || (removed_ids && g->n_rep_rem > cap_r))
        return sooc_seterr(SOOC_EINVAL, "mapper changed: %zu changed / %zu removed do not fit in %zu / %zu", g->n_chg,
                           g->n_rep_rem, cap, cap_r);
    for (size_t i = 0; out && i < g->n_chg; i++) {
        size_t j = 0;
        while (j < g->n && g->ent[j].e.id != g->chg[i]) j++;
        if (j == g->n) return sooc_seterr(SOOC_EINVAL, "mapper changed: entry %llu gone", (unsigned long long)g->chg[i]);
        out[i] = g->ent[j].e;
    }
    if (removed_ids) memcpy(removed_ids, g->rep_rem, g->n_rep_rem * sizeof *removed_ids);
    return SOOC_OK;
}
