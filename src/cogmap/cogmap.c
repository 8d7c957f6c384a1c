/*
 * The cognitive map (docs/cogmap.md): dense entry storage, an id -> slot hash,
 * a floor-plane hash grid, query / registration and layout blocks.
 *
 * Storage:
 *  - entries live in a dense array (swap-remove on deletion, so removal is
 *    O(1)); a parallel array records each entry's grid cell and its position
 *    inside that cell's member list;
 *  - id -> dense index: open addressing, linear probing, backward-shift
 *    deletion (no tombstones);
 *  - grid: (ci, cj) -> cell; a cell holds a growable member list of
 *    {X, Z, dense index} so the footprint pre-filter touches only the cell;
 *    cells are never freed before clear/destroy;
 *  - layout blocks: (bi, bj) -> block index, latents in a slab.
 * A query visits only the cells overlapping the axis-aligned bounding box of
 * the frustum's floor footprint up to d_clip, so its cost is set by the local
 * density, not by the number of entries.
 */
#include "cogmap_impl.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* ------------------------------------------------------------ u64 -> u32 hash */

static uint64_t mix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

static void hmap_free(sooc_hmap *h) {
    sooc_free(h->s);
    memset(h, 0, sizeof *h);
}

static sooc_status hmap_init(sooc_hmap *h, size_t cap) {
    size_t c = 16;
    while (c < cap) c <<= 1;
    h->s = sooc_malloc(c * sizeof *h->s);
    if (!h->s) return sooc_seterr(SOOC_ENOMEM, "cogmap: hash table of %zu slots", c);
    for (size_t i = 0; i < c; i++) h->s[i].val = SOOC_HEMPTY;
    h->cap = c;
    h->n = 0;
    return SOOC_OK;
}

static void hmap_reset(sooc_hmap *h) {
    for (size_t i = 0; i < h->cap; i++) h->s[i].val = SOOC_HEMPTY;
    h->n = 0;
}

static uint32_t hmap_get(const sooc_hmap *h, uint64_t key) {
    size_t mask = h->cap - 1, i = (size_t)mix64(key) & mask;
    for (;;) {
        const sooc_hslot *sl = &h->s[i];
        if (sl->val == SOOC_HEMPTY) return SOOC_HEMPTY;
        if (sl->key == key) return sl->val;
        i = (i + 1) & mask;
    }
}

static void hmap_put_noresize(sooc_hmap *h, uint64_t key, uint32_t val) {
    size_t mask = h->cap - 1, i = (size_t)mix64(key) & mask;
    for (;;) {
        sooc_hslot *sl = &h->s[i];
        if (sl->val == SOOC_HEMPTY) {
            sl->key = key;
            sl->val = val;
            h->n++;
            return;
        }
        if (sl->key == key) {
            sl->val = val;
            return;
        }
        i = (i + 1) & mask;
    }
}

static sooc_status hmap_grow(sooc_hmap *h, size_t cap) {
    sooc_hmap g = {0};
    sooc_status s = hmap_init(&g, cap);
    if (s) return s;
    for (size_t i = 0; i < h->cap; i++)
        if (h->s[i].val != SOOC_HEMPTY) hmap_put_noresize(&g, h->s[i].key, h->s[i].val);
    hmap_free(h);
    *h = g;
    return SOOC_OK;
}

/* Insert or overwrite; grows to keep the load factor <= 1/2. */
static sooc_status hmap_put(sooc_hmap *h, uint64_t key, uint32_t val) {
    if ((h->n + 1) * 2 > h->cap) {
        sooc_status s = hmap_grow(h, h->cap * 2);
        if (s) return s;
    }
    hmap_put_noresize(h, key, val);
    return SOOC_OK;
}

/* Delete with backward shift (keeps probe chains intact without tombstones). */
static void hmap_del(sooc_hmap *h, uint64_t key) {
    size_t mask = h->cap - 1, i = (size_t)mix64(key) & mask;
    for (;;) {
        if (h->s[i].val == SOOC_HEMPTY) return;
        if (h->s[i].key == key) break;
        i = (i + 1) & mask;
    }
    h->n--;
    size_t j = i;
    for (;;) {
        h->s[i].val = SOOC_HEMPTY;
        for (;;) {
            j = (j + 1) & mask;
            if (h->s[j].val == SOOC_HEMPTY) return;
            size_t home = (size_t)mix64(h->s[j].key) & mask;
            /* move j to i unless home lies cyclically in (i, j] */
            if (i <= j ? (i < home && home <= j) : (i < home || home <= j)) continue;
            break;
        }
        h->s[i] = h->s[j];
        i = j;
    }
}

static uint64_t pack2(int32_t a, int32_t b) { return ((uint64_t)(uint32_t)a << 32) | (uint32_t)b; }

/* ------------------------------------------------------------- lifecycle */

void sooc_cogmap_params_default(sooc_cogmap_params *p) {
    p->dim = 32;
    p->layout_dim = 16;
    p->cell_size = 4.0;
    p->block_size = 4.0;
    p->capacity = 1024;
}

sooc_status sooc_cogmap_create(sooc_cogmap **out, const sooc_cogmap_params *p) {
    *out = NULL;
    sooc_cogmap_params d;
    if (!p) {
        sooc_cogmap_params_default(&d);
        p = &d;
    }
    if (p->dim < 1 || p->dim > SOOC_COGMAP_DIM_MAX)
        return sooc_seterr(SOOC_EINVAL, "cogmap: latent dim %d outside 1..%d", p->dim, SOOC_COGMAP_DIM_MAX);
    if (p->layout_dim < 0 || p->layout_dim > SOOC_COGMAP_DIM_MAX)
        return sooc_seterr(SOOC_EINVAL, "cogmap: layout dim %d outside 0..%d", p->layout_dim,
                           SOOC_COGMAP_DIM_MAX);
    if (!(p->cell_size > 0.01 && p->cell_size < 1e4) || !(p->block_size > 0.01 && p->block_size < 1e5))
        return sooc_seterr(SOOC_EINVAL, "cogmap: cell_size %g / block_size %g out of range", p->cell_size,
                           p->block_size);
    sooc_cogmap *m = sooc_calloc(1, sizeof *m);
    if (!m) return SOOC_ENOMEM;
    m->dim = p->dim;
    m->ldim = p->layout_dim;
    m->cell = p->cell_size;
    m->inv_cell = 1.0 / p->cell_size;
    m->block = p->block_size;
    m->next_id = 1;
    size_t cap = p->capacity ? p->capacity : 16;
    sooc_status s;
    m->ent = sooc_malloc(cap * sizeof *m->ent);
    m->loc = sooc_malloc(cap * sizeof *m->loc);
    if (!m->ent || !m->loc) { s = SOOC_ENOMEM; goto fail; }
    m->ent_cap = cap;
    if ((s = hmap_init(&m->ids, cap * 2))) goto fail;
    if ((s = hmap_init(&m->cells_h, 64))) goto fail;
    if ((s = hmap_init(&m->blocks_h, 64))) goto fail;
    *out = m;
    return SOOC_OK;
fail:
    sooc_cogmap_destroy(m);
    return s ? s : sooc_seterr(SOOC_ENOMEM, "cogmap: out of memory");
}

void sooc_cogmap_destroy(sooc_cogmap *m) {
    if (!m) return;
    for (size_t i = 0; i < m->n_cells; i++) sooc_free(m->cells[i].mem);
    sooc_free(m->cells);
    sooc_free(m->ent);
    sooc_free(m->loc);
    sooc_free(m->blk_key);
    sooc_free(m->blk_lat);
    hmap_free(&m->ids);
    hmap_free(&m->cells_h);
    hmap_free(&m->blocks_h);
    sooc_cogmap_payloads_free(m);
    sooc_free(m);
}

void sooc_cogmap_clear(sooc_cogmap *m, int reset_ids) {
    for (size_t i = 0; i < m->n_cells; i++) sooc_free(m->cells[i].mem);
    m->n_cells = 0;
    m->n = 0;
    m->n_blk = 0;
    hmap_reset(&m->ids);
    hmap_reset(&m->cells_h);
    hmap_reset(&m->blocks_h);
    sooc_cogmap_payloads_free(m);
    if (reset_ids) m->next_id = 1;
}

int sooc_cogmap_dim(const sooc_cogmap *m) { return m->dim; }
int sooc_cogmap_layout_dim(const sooc_cogmap *m) { return m->ldim; }
size_t sooc_cogmap_count(const sooc_cogmap *m) { return m->n; }
uint64_t sooc_cogmap_next_id(const sooc_cogmap *m) { return m->next_id; }
void sooc_cogmap_reserve_ids(sooc_cogmap *m, uint64_t next) {
    if (next > m->next_id) m->next_id = next;
}

/* ------------------------------------------------------------ grid cells */

static void cell_coords(const sooc_cogmap *m, double X, double Z, int32_t *ci, int32_t *cj) {
    double a = floor(X * m->inv_cell), b = floor(Z * m->inv_cell);
    /* clamp far-away values so the int conversion stays defined */
    if (a < -2e9) a = -2e9;
    if (a > 2e9) a = 2e9;
    if (b < -2e9) b = -2e9;
    if (b > 2e9) b = 2e9;
    *ci = (int32_t)a;
    *cj = (int32_t)b;
}

/* The cell (ci, cj), or NULL if it holds no entry yet. */
static const sooc_cell *cell_at(const sooc_cogmap *m, int32_t ci, int32_t cj) {
    uint32_t c = hmap_get(&m->cells_h, pack2(ci, cj));
    return c == SOOC_HEMPTY ? NULL : &m->cells[c];
}

/* Find or create the cell (ci, cj); returns its index or SOOC_HEMPTY on ENOMEM. */
static uint32_t cell_get_or_add(sooc_cogmap *m, int32_t ci, int32_t cj) {
    uint64_t key = pack2(ci, cj);
    uint32_t c = hmap_get(&m->cells_h, key);
    if (c != SOOC_HEMPTY) return c;
    if (m->n_cells == m->cap_cells) {
        size_t nc = m->cap_cells ? m->cap_cells * 2 : 64;
        sooc_cell *p = sooc_realloc(m->cells, nc * sizeof *p);
        if (!p) return SOOC_HEMPTY;
        m->cells = p;
        m->cap_cells = nc;
    }
    if (hmap_put(&m->cells_h, key, (uint32_t)m->n_cells)) return SOOC_HEMPTY;
    sooc_cell *cl = &m->cells[m->n_cells];
    memset(cl, 0, sizeof *cl);
    cl->ci = ci;
    cl->cj = cj;
    return (uint32_t)m->n_cells++;
}

static sooc_status cell_add(sooc_cogmap *m, uint32_t c, uint32_t idx) {
    sooc_cell *cl = &m->cells[c];
    if (cl->n == cl->cap) {
        uint32_t nc = cl->cap ? cl->cap * 2 : 8;
        sooc_cell_member *p = sooc_realloc(cl->mem, (size_t)nc * sizeof *p);
        if (!p) return sooc_seterr(SOOC_ENOMEM, "cogmap: grid cell growth");
        cl->mem = p;
        cl->cap = nc;
    }
    cl->mem[cl->n].X = m->ent[idx].X;
    cl->mem[cl->n].Z = m->ent[idx].Z;
    cl->mem[cl->n].id = m->ent[idx].id;
    cl->mem[cl->n].pres = m->ent[idx].pres_logit;
    cl->mem[cl->n].idx = idx;
    m->loc[idx].cell = c;
    m->loc[idx].slot = cl->n;
    cl->n++;
    return SOOC_OK;
}

static void cell_del(sooc_cogmap *m, uint32_t idx) {
    sooc_cell *cl = &m->cells[m->loc[idx].cell];
    uint32_t s = m->loc[idx].slot, last = cl->n - 1;
    if (s != last) {
        cl->mem[s] = cl->mem[last];
        m->loc[cl->mem[s].idx].slot = s;
    }
    cl->n--;
}

/* ------------------------------------------------------------- entries */

static int entry_finite(const sooc_cogmap_entry *e) {
    if (!isfinite(e->X) || !isfinite(e->Z) || !isfinite(e->Theta) || !isfinite(e->rho_t) ||
        !isfinite(e->rho_theta) || !isfinite(e->pres_logit))
        return 0;
    for (int i = 0; i < e->dim; i++)
        if (!isfinite(e->what_mu[i]) || !isfinite(e->what_logvar[i])) return 0;
    return 1;
}

static sooc_status ent_reserve(sooc_cogmap *m, size_t need) {
    if (need <= m->ent_cap) return SOOC_OK;
    size_t nc = m->ent_cap * 2;
    while (nc < need) nc *= 2;
    sooc_cogmap_entry *e = sooc_realloc(m->ent, nc * sizeof *e);
    if (!e) return sooc_seterr(SOOC_ENOMEM, "cogmap: %zu entries", nc);
    m->ent = e;
    sooc_loc *l = sooc_realloc(m->loc, nc * sizeof *l);
    if (!l) return sooc_seterr(SOOC_ENOMEM, "cogmap: %zu entries", nc);
    m->loc = l;
    m->ent_cap = nc;
    return SOOC_OK;
}

/* Normalise an entry's unused tails so stored entries compare with memcmp. */
static void entry_canon(sooc_cogmap_entry *dst, const sooc_cogmap_entry *src, int d) {
    memset(dst, 0, sizeof *dst);
    dst->id = src->id;
    dst->X = src->X;
    dst->Z = src->Z;
    dst->Theta = src->Theta;
    dst->rho_t = src->rho_t;
    dst->rho_theta = src->rho_theta;
    dst->pres_logit = src->pres_logit;
    dst->dim = d;
    memcpy(dst->what_mu, src->what_mu, (size_t)d * sizeof(float));
    memcpy(dst->what_logvar, src->what_logvar, (size_t)d * sizeof(float));
    dst->first_seen_ns = src->first_seen_ns;
    dst->last_seen_ns = src->last_seen_ns;
    dst->obs_count = src->obs_count;
    dst->last_view = src->last_view;
}

/* Write a canonical entry (id set, non-zero) into the map: overwrite or append. */
static sooc_status ent_put(sooc_cogmap *m, const sooc_cogmap_entry *e) {
    uint32_t idx = hmap_get(&m->ids, e->id);
    int32_t ci, cj;
    cell_coords(m, e->X, e->Z, &ci, &cj);
    if (idx != SOOC_HEMPTY) {
        sooc_cell *cl = &m->cells[m->loc[idx].cell];
        m->ent[idx] = *e;
        if (cl->ci == ci && cl->cj == cj) {
            cl->mem[m->loc[idx].slot].X = e->X;
            cl->mem[m->loc[idx].slot].Z = e->Z;
            cl->mem[m->loc[idx].slot].pres = e->pres_logit;
            return SOOC_OK;
        }
        uint32_t c = cell_get_or_add(m, ci, cj);
        if (c == SOOC_HEMPTY) return sooc_seterr(SOOC_ENOMEM, "cogmap: grid cell");
        /* reserve room in the target cell before unlinking, so failure leaves a consistent map */
        sooc_cell *nc = &m->cells[c];
        if (nc->n == nc->cap) {
            uint32_t cap = nc->cap ? nc->cap * 2 : 8;
            sooc_cell_member *p = sooc_realloc(nc->mem, (size_t)cap * sizeof *p);
            if (!p) return sooc_seterr(SOOC_ENOMEM, "cogmap: grid cell growth");
            nc->mem = p;
            nc->cap = cap;
        }
        cell_del(m, idx);
        return cell_add(m, c, idx);
    }
    sooc_status s = ent_reserve(m, m->n + 1);
    if (s) return s;
    uint32_t c = cell_get_or_add(m, ci, cj);
    if (c == SOOC_HEMPTY) return sooc_seterr(SOOC_ENOMEM, "cogmap: grid cell");
    idx = (uint32_t)m->n;
    m->ent[idx] = *e;
    if ((s = hmap_put(&m->ids, e->id, idx))) return s;
    if ((s = cell_add(m, c, idx))) {
        hmap_del(&m->ids, e->id);
        return s;
    }
    m->n++;
    if (e->id >= m->next_id) m->next_id = e->id + 1;
    return SOOC_OK;
}

static void ent_del_at(sooc_cogmap *m, uint32_t idx) {
    cell_del(m, idx);
    hmap_del(&m->ids, m->ent[idx].id);
    uint32_t last = (uint32_t)m->n - 1;
    if (idx != last) {
        m->ent[idx] = m->ent[last];
        m->loc[idx] = m->loc[last];
        m->cells[m->loc[idx].cell].mem[m->loc[idx].slot].idx = idx;
        hmap_put_noresize(&m->ids, m->ent[idx].id, idx); /* key exists: overwrite, no growth */
    }
    m->n--;
}

sooc_status sooc_cogmap_get(const sooc_cogmap *m, uint64_t id, sooc_cogmap_entry *out) {
    uint32_t idx = id ? hmap_get(&m->ids, id) : SOOC_HEMPTY;
    if (idx == SOOC_HEMPTY) return sooc_seterr(SOOC_ENOTFOUND, "cogmap: no entry with id %llu",
                                               (unsigned long long)id);
    *out = m->ent[idx];
    return SOOC_OK;
}

sooc_status sooc_cogmap_insert(sooc_cogmap *m, const sooc_cogmap_entry *e, uint64_t *id_out) {
    if (e->dim != m->dim)
        return sooc_seterr(SOOC_EINVAL, "cogmap: entry dim %d, map dim %d", e->dim, m->dim);
    if (!entry_finite(e))
        return sooc_seterr(SOOC_ENUMERIC, "cogmap: entry %llu has non-finite values", (unsigned long long)e->id);
    sooc_cogmap_entry c;
    entry_canon(&c, e, m->dim);
    c.Theta = sooc_wrap_angle(c.Theta);
    if (!c.id) c.id = m->next_id;
    sooc_status s = ent_put(m, &c);
    if (s) return s;
    if (c.id >= m->next_id) m->next_id = c.id + 1;
    if (id_out) *id_out = c.id;
    return SOOC_OK;
}

sooc_status sooc_cogmap_remove(sooc_cogmap *m, uint64_t id) {
    uint32_t idx = id ? hmap_get(&m->ids, id) : SOOC_HEMPTY;
    if (idx == SOOC_HEMPTY) return sooc_seterr(SOOC_ENOTFOUND, "cogmap: no entry with id %llu",
                                               (unsigned long long)id);
    ent_del_at(m, idx);
    return SOOC_OK;
}

static int cmp_entry_id(const void *a, const void *b) {
    uint64_t x = ((const sooc_cogmap_entry *)a)->id, y = ((const sooc_cogmap_entry *)b)->id;
    return x < y ? -1 : x > y;
}
static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return x < y ? -1 : x > y;
}

sooc_status sooc_cogmap_entries(const sooc_cogmap *m, sooc_cogmap_entry *out, size_t cap, size_t *n) {
    if (!out) {
        *n = m->n;
        return SOOC_OK;
    }
    if (cap >= m->n) {
        if (m->n) memcpy(out, m->ent, m->n * sizeof *out);
        qsort(out, m->n, sizeof *out, cmp_entry_id);
        *n = m->n;
        return SOOC_OK;
    }
    /* fewer than all: the `cap` smallest ids, via a sorted id list */
    uint64_t *ids = sooc_malloc((m->n ? m->n : 1) * sizeof *ids);
    if (!ids) return SOOC_ENOMEM;
    for (size_t i = 0; i < m->n; i++) ids[i] = m->ent[i].id;
    qsort(ids, m->n, sizeof *ids, cmp_u64);
    for (size_t i = 0; i < cap; i++) out[i] = m->ent[hmap_get(&m->ids, ids[i])];
    sooc_free(ids);
    *n = cap;
    return SOOC_OK;
}

sooc_status sooc_cogmap_load(sooc_cogmap *m, const sooc_cogmap_entry *e, size_t n) {
    uint64_t maxid = 0;
    uint64_t *ids = sooc_malloc((n ? n : 1) * sizeof *ids);
    if (!ids) return SOOC_ENOMEM;
    sooc_status s = SOOC_OK;
    for (size_t i = 0; i < n && !s; i++) {
        if (!e[i].id) s = sooc_seterr(SOOC_EINVAL, "cogmap load: entry %zu has id 0", i);
        else if (e[i].dim != m->dim)
            s = sooc_seterr(SOOC_EINVAL, "cogmap load: entry %llu dim %d, map dim %d",
                            (unsigned long long)e[i].id, e[i].dim, m->dim);
        else if (!entry_finite(&e[i]))
            s = sooc_seterr(SOOC_ENUMERIC, "cogmap load: entry %llu has non-finite values",
                            (unsigned long long)e[i].id);
        ids[i] = e[i].id;
        if (e[i].id > maxid) maxid = e[i].id;
    }
    if (!s) {
        qsort(ids, n, sizeof *ids, cmp_u64);
        for (size_t i = 1; i < n; i++)
            if (ids[i] == ids[i - 1]) {
                s = sooc_seterr(SOOC_EINVAL, "cogmap load: duplicate id %llu", (unsigned long long)ids[i]);
                break;
            }
    }
    sooc_free(ids);
    if (s) return s;
    /* drop entries, keep layout blocks */
    for (size_t i = 0; i < m->n_cells; i++) m->cells[i].n = 0;
    hmap_reset(&m->ids);
    m->n = 0;
    if ((s = ent_reserve(m, n))) return s;
    for (size_t i = 0; i < n; i++) {
        sooc_cogmap_entry c;
        entry_canon(&c, &e[i], m->dim);
        if ((s = ent_put(m, &c))) return s;
    }
    sooc_cogmap_reserve_ids(m, maxid + 1);
    return SOOC_OK;
}

int sooc_cogmap_foreach(const sooc_cogmap *m, sooc_cogmap_visit_fn fn, void *user) {
    for (size_t i = 0; i < m->n; i++) {
        int r = fn(user, &m->ent[i]);
        if (r) return r;
    }
    return 0;
}

/* ------------------------------------------------------ frame transforms */

void sooc_cogmap_lam_to_local(const sooc_floor_frame *f, const sooc_cogmap_entry *e, float *lam) {
    int d = e->dim;
    double w[3] = {e->X, e->Z, e->Theta}, l[3];
    sooc_floor_to_local(f, w, l);
    lam[SOOC_LAM_X] = (float)l[0];
    lam[SOOC_LAM_Z] = (float)l[1];
    lam[SOOC_LAM_TH] = (float)l[2];
    lam[SOOC_LAM_RHO_T] = e->rho_t;
    lam[SOOC_LAM_RHO_TH] = e->rho_theta;
    memcpy(lam + SOOC_LAM_WHAT_MU, e->what_mu, (size_t)d * sizeof(float));
    memcpy(lam + SOOC_LAM_WHAT_LV(d), e->what_logvar, (size_t)d * sizeof(float));
    lam[SOOC_LAM_PRES(d)] = e->pres_logit;
}

void sooc_cogmap_lam_to_world(const sooc_floor_frame *f, int d, const float *lam, sooc_cogmap_entry *e) {
    double l[3] = {lam[SOOC_LAM_X], lam[SOOC_LAM_Z], lam[SOOC_LAM_TH]}, w[3];
    sooc_floor_to_world(f, l, w);
    e->X = w[0];
    e->Z = w[1];
    e->Theta = w[2];
    e->rho_t = lam[SOOC_LAM_RHO_T];
    e->rho_theta = lam[SOOC_LAM_RHO_TH];
    e->dim = d;
    memset(e->what_mu, 0, sizeof e->what_mu);
    memset(e->what_logvar, 0, sizeof e->what_logvar);
    memcpy(e->what_mu, lam + SOOC_LAM_WHAT_MU, (size_t)d * sizeof(float));
    memcpy(e->what_logvar, lam + SOOC_LAM_WHAT_LV(d), (size_t)d * sizeof(float));
    e->pres_logit = lam[SOOC_LAM_PRES(d)];
}

/* l = R2(psi)^T (W - C), R2 = [[c, s], [-s, c]]  =>  dL/dW = R2 dL/dl. */
void sooc_cogmap_grad_local_to_world(const sooc_floor_frame *f, int d, const float *gl, float *gw) {
    double c = cos(f->psi), s = sin(f->psi);
    double gx = gl[SOOC_LAM_X], gz = gl[SOOC_LAM_Z];
    gw[SOOC_LAM_X] += (float)(c * gx + s * gz);
    gw[SOOC_LAM_Z] += (float)(-s * gx + c * gz);
    for (int i = SOOC_LAM_TH; i < SOOC_LAM_SIZE(d); i++) gw[i] += gl[i];
}

/* W = R2(psi) l + C  =>  dL/dl = R2^T dL/dW. */
void sooc_cogmap_grad_world_to_local(const sooc_floor_frame *f, int d, const float *gw, float *gl) {
    double c = cos(f->psi), s = sin(f->psi);
    double gx = gw[SOOC_LAM_X], gz = gw[SOOC_LAM_Z];
    gl[SOOC_LAM_X] += (float)(c * gx - s * gz);
    gl[SOOC_LAM_Z] += (float)(s * gx + c * gz);
    for (int i = SOOC_LAM_TH; i < SOOC_LAM_SIZE(d); i++) gl[i] += gw[i];
}

void sooc_cogmap_grad_route(const sooc_floor_frame *f_reg, const sooc_floor_frame *f_query, int d,
                            const float *g_query, float *g_reg) {
    float gw[SOOC_LAM_MAX];
    memset(gw, 0, sizeof gw);
    sooc_cogmap_grad_local_to_world(f_query, d, g_query, gw);
    sooc_cogmap_grad_world_to_local(f_reg, d, gw, g_reg);
}

/* ----------------------------------------------------------------- query */

/* Camera quantities shared by the in-view tests of one query. */
typedef struct qcam {
    double R[9], t[3];  /* world -> camera */
    double fx, fy, cx, cy, W, H, t_near, d_clip, R_h, H_b;
    int corners;
} qcam;

static void qcam_init(qcam *q, const sooc_cogmap_camera *cam) {
    double T_cw[16];
    sooc_se3_inverse(T_cw, cam->T_wc);
    sooc_se3_to_rt(q->R, q->t, T_cw);
    q->fx = cam->K.fx;
    q->fy = cam->K.fy;
    q->cx = cam->K.cx;
    q->cy = cam->K.cy;
    q->W = cam->K.width;
    q->H = cam->K.height;
    q->t_near = cam->t_near;
    q->d_clip = cam->d_clip;
    q->R_h = cam->R_h;
    q->H_b = cam->H_b;
    q->corners = cam->mode == SOOC_INVIEW_CORNERS;
}

static int point_in_view(const qcam *q, double X, double Y, double Z) {
    const double *R = q->R;
    double z = R[6] * X + R[7] * Y + R[8] * Z + q->t[2];
    if (!(z > q->t_near && z < q->d_clip)) return 0;
    double x = R[0] * X + R[1] * Y + R[2] * Z + q->t[0];
    double y = R[3] * X + R[4] * Y + R[5] * Z + q->t[1];
    double u = q->fx * x / z + q->cx, v = q->fy * y / z + q->cy;
    return u >= 0 && u < q->W && v >= 0 && v < q->H;
}

static int qcam_in_view(const qcam *q, const sooc_cogmap_entry *e) {
    if (!q->corners) return point_in_view(q, e->X, 0.5 * q->H_b, e->Z);
    double c = cos(e->Theta), s = sin(e->Theta);
    for (int a = -1; a <= 1; a += 2)
        for (int b = -1; b <= 1; b += 2) {
            /* R_y(Θ) (a R_h, ., b R_h): x' = c x + s z, z' = -s x + c z */
            double lx = a * q->R_h, lz = b * q->R_h;
            double X = e->X + c * lx + s * lz, Z = e->Z - s * lx + c * lz;
            if (point_in_view(q, X, 0, Z) || point_in_view(q, X, q->H_b, Z)) return 1;
        }
    return 0;
}

static sooc_status check_camera(const sooc_cogmap_camera *cam) {
    if (cam->K.width <= 0 || cam->K.height <= 0 || !(cam->K.fx > 0) || !(cam->K.fy > 0))
        return sooc_seterr(SOOC_EINVAL, "cogmap query: bad intrinsics (%dx%d, fx %g, fy %g)", cam->K.width,
                           cam->K.height, cam->K.fx, cam->K.fy);
    if (!(cam->t_near >= 0) || !(cam->d_clip > cam->t_near) || !isfinite(cam->d_clip))
        return sooc_seterr(SOOC_EINVAL, "cogmap query: bad depth range (%g, %g)", cam->t_near, cam->d_clip);
    if (!(cam->R_h >= 0) || !(cam->H_b >= 0))
        return sooc_seterr(SOOC_EINVAL, "cogmap query: bad box R_h %g H_b %g", cam->R_h, cam->H_b);
    for (int i = 0; i < 16; i++)
        if (!isfinite(cam->T_wc[i])) return sooc_seterr(SOOC_ENUMERIC, "cogmap query: non-finite pose");
    return SOOC_OK;
}

int sooc_cogmap_in_view(const sooc_cogmap_camera *cam, const sooc_cogmap_entry *e) {
    qcam q;
    qcam_init(&q, cam);
    return qcam_in_view(&q, e);
}

/* Axis-aligned box on (X, Z) holding the floor projection of the frustum
 * (camera depth in [t_near, d_clip], inside the image), grown by `margin`. */
static void footprint_aabb(const sooc_cogmap_camera *cam, double margin, double lo[2], double hi[2]) {
    lo[0] = lo[1] = INFINITY;
    hi[0] = hi[1] = -INFINITY;
    const double us[2] = {0, cam->K.width}, vs[2] = {0, cam->K.height}, zs[2] = {cam->t_near, cam->d_clip};
    for (int a = 0; a < 2; a++)
        for (int b = 0; b < 2; b++)
            for (int c = 0; c < 2; c++) {
                double z = zs[c];
                double p[3] = {(us[a] - cam->K.cx) / cam->K.fx * z, (vs[b] - cam->K.cy) / cam->K.fy * z, z}, w[3];
                sooc_se3_apply(w, cam->T_wc, p);
                if (w[0] < lo[0]) lo[0] = w[0];
                if (w[0] > hi[0]) hi[0] = w[0];
                if (w[2] < lo[1]) lo[1] = w[2];
                if (w[2] > hi[1]) hi[1] = w[2];
            }
    lo[0] -= margin;
    lo[1] -= margin;
    hi[0] += margin;
    hi[1] += margin;
}

typedef struct cand {
    float pres;
    uint64_t id;
    uint32_t idx;
} cand;

/* a ranks before b: higher presence logit, then smaller id */
static int cand_before(float pa, uint64_t ia, float pb, uint64_t ib) {
    return pa > pb || (pa == pb && ia < ib);
}

sooc_status sooc_cogmap_query(const sooc_cogmap *m, const sooc_cogmap_camera *cam, int k, sooc_cogmap_slot *out,
                              int *n_out, sooc_floor_frame *gf, int *n_inview) {
    *n_out = 0;
    if (n_inview) *n_inview = 0;
    if (k < 0 || k > SOOC_COGMAP_K_MAX)
        return sooc_seterr(SOOC_EINVAL, "cogmap query: k = %d outside 0..%d", k, SOOC_COGMAP_K_MAX);
    sooc_status s = check_camera(cam);
    if (s) return s;
    double T_wg[16];
    if ((s = sooc_gframe(cam->T_wc, T_wg, NULL, NULL, NULL))) return s;
    sooc_floor_frame f;
    sooc_floor_frame_of(&f, T_wg);
    if (gf) *gf = f;

    qcam q;
    qcam_init(&q, cam);
    /* the box centre lies in the frustum (centre mode); with corners, the
     * centre is within sqrt(2) R_h of a corner that does */
    double margin = (q.corners ? 1.4142135623730951 * cam->R_h : 0) + 1e-9;
    double lo[2], hi[2];
    footprint_aabb(cam, margin, lo, hi);
    int32_t ci0, cj0, ci1, cj1;
    cell_coords(m, lo[0], lo[1], &ci0, &cj0);
    cell_coords(m, hi[0], hi[1], &ci1, &cj1);

    cand best[SOOC_COGMAP_K_MAX];
    int nb = 0, nin = 0;
    for (int64_t ci = ci0; ci <= ci1; ci++)
        for (int64_t cj = cj0; cj <= cj1; cj++) {
            const sooc_cell *cl = cell_at(m, (int32_t)ci, (int32_t)cj);
            if (!cl) continue;
            for (uint32_t i = 0; i < cl->n; i++) {
                const sooc_cell_member *mb = &cl->mem[i];
                if (mb->X < lo[0] || mb->X > hi[0] || mb->Z < lo[1] || mb->Z > hi[1]) continue;
                if (q.corners ? !qcam_in_view(&q, &m->ent[mb->idx]) : !point_in_view(&q, mb->X, 0.5 * q.H_b, mb->Z))
                    continue;
                nin++;
                if (k == 0) continue;
                if (nb == k && !cand_before(mb->pres, mb->id, best[k - 1].pres, best[k - 1].id)) continue;
                int j = nb < k ? nb++ : k - 1;
                while (j > 0 && cand_before(mb->pres, mb->id, best[j - 1].pres, best[j - 1].id)) {
                    best[j] = best[j - 1];
                    j--;
                }
                best[j].pres = mb->pres;
                best[j].id = mb->id;
                best[j].idx = mb->idx;
            }
        }
    for (int i = 0; i < nb; i++) {
        const sooc_cogmap_entry *e = &m->ent[best[i].idx];
        sooc_cogmap_slot *sl = &out[i];
        memset(sl, 0, sizeof *sl);
        sl->id = e->id;
        sl->last_view = e->last_view;
        sooc_cogmap_lam_to_local(&f, e, sl->lam);
    }
    *n_out = nb;
    if (n_inview) *n_inview = nin;
    return SOOC_OK;
}

/* ----------------------------------------------------------- registration */

sooc_status sooc_cogmap_register(sooc_cogmap *m, const sooc_floor_frame *gf, int k, const float *lam,
                                 const uint64_t *src_ids, int64_t t_ns, int32_t view, uint64_t *ids_out,
                                 uint64_t *removed_out, sooc_cogmap_reg_stats *st) {
    sooc_cogmap_reg_stats z = {0};
    if (st) *st = z;
    int d = m->dim, S = SOOC_LAM_SIZE(d);
    if (k < 0 || k > SOOC_COGMAP_K_MAX)
        return sooc_seterr(SOOC_EINVAL, "cogmap register: k = %d outside 0..%d", k, SOOC_COGMAP_K_MAX);
    if (!isfinite(gf->X) || !isfinite(gf->Z) || !isfinite(gf->psi))
        return sooc_seterr(SOOC_ENUMERIC, "cogmap register: non-finite view frame");
    /* validate everything before touching the map */
    for (int i = 0; i < k; i++) {
        for (int j = 0; j < S; j++)
            if (!isfinite(lam[(size_t)i * S + j]))
                return sooc_seterr(SOOC_ENUMERIC, "cogmap register: slot %d lambda[%d] is not finite", i, j);
        uint64_t id = src_ids ? src_ids[i] : 0;
        if (!id) continue;
        if (hmap_get(&m->ids, id) == SOOC_HEMPTY)
            return sooc_seterr(SOOC_ENOTFOUND, "cogmap register: slot %d: source id %llu is not in the map", i,
                               (unsigned long long)id);
        for (int j = 0; j < i; j++)
            if (src_ids[j] == id)
                return sooc_seterr(SOOC_EINVAL, "cogmap register: slots %d and %d share source id %llu", j, i,
                                   (unsigned long long)id);
    }
    /* room for the new entries up front, so an ENOMEM cannot leave half a view */
    int n_new = 0;
    for (int i = 0; i < k; i++)
        if (lam[(size_t)i * S + SOOC_LAM_PRES(d)] >= 0.0f && !(src_ids && src_ids[i])) n_new++;
    sooc_status s = ent_reserve(m, m->n + (size_t)n_new);
    if (s) return s;
    /* grow the id table now, so the puts below cannot fail */
    if ((m->ids.n + (size_t)n_new) * 2 > m->ids.cap && (s = hmap_grow(&m->ids, 2 * (m->ids.n + (size_t)n_new))))
        return s;

    sooc_cogmap_reg_stats r = {0};
    for (int i = 0; i < k; i++) {
        const float *l = lam + (size_t)i * S;
        uint64_t src = src_ids ? src_ids[i] : 0;
        if (ids_out) ids_out[i] = 0;
        if (!(l[SOOC_LAM_PRES(d)] >= 0.0f)) {
            if (src) {
                ent_del_at(m, hmap_get(&m->ids, src));
                if (removed_out) removed_out[r.n_removed] = src;
                r.n_removed++;
            }
            continue;
        }
        sooc_cogmap_entry e;
        if (src) {
            e = m->ent[hmap_get(&m->ids, src)];
            e.obs_count++;
            r.n_updated++;
        } else {
            memset(&e, 0, sizeof e);
            e.id = m->next_id++;
            e.first_seen_ns = t_ns;
            e.obs_count = 1;
            r.n_new++;
        }
        sooc_cogmap_lam_to_world(gf, d, l, &e);
        e.last_seen_ns = t_ns;
        e.last_view = view;
        if ((s = ent_put(m, &e))) {
            if (st) *st = r;
            return s;
        }
        if (ids_out) ids_out[i] = e.id;
        r.n_registered++;
    }
    if (st) *st = r;
    return SOOC_OK;
}

/* 1 if an entry outside ids[0..k) lies closer than r to (X, Z) on the floor. */
static int near_other(const sooc_cogmap *m, double X, double Z, double r, const uint64_t *ids, int k) {
    int32_t ci0, cj0, ci1, cj1;
    cell_coords(m, X - r, Z - r, &ci0, &cj0);
    cell_coords(m, X + r, Z + r, &ci1, &cj1);
    for (int64_t ci = ci0; ci <= ci1; ci++)
        for (int64_t cj = cj0; cj <= cj1; cj++) {
            const sooc_cell *cl = cell_at(m, (int32_t)ci, (int32_t)cj);
            if (!cl) continue;
            for (uint32_t i = 0; i < cl->n; i++) {
                const sooc_cell_member *mb = &cl->mem[i];
                double dx = mb->X - X, dz = mb->Z - Z;
                if (!(dx * dx + dz * dz < r * r)) continue;
                int listed = 0;
                for (int j = 0; j < k && !listed; j++) listed = ids[j] == mb->id;
                if (!listed) return 1;
            }
        }
    return 0;
}

void sooc_cogmap_merge(sooc_cogmap *m, uint64_t *ids, int k, double radius, uint64_t *removed_out,
                       int *n_removed) {
    int nr = 0;
    for (int i = 0; radius > 0 && i < k; i++) {
        uint32_t a = ids[i] ? hmap_get(&m->ids, ids[i]) : SOOC_HEMPTY;
        for (int j = i + 1; a != SOOC_HEMPTY && j < k; j++) {
            uint32_t b = ids[j] ? hmap_get(&m->ids, ids[j]) : SOOC_HEMPTY;
            if (b == SOOC_HEMPTY) continue;
            const sooc_cogmap_entry *ea = &m->ent[a], *eb = &m->ent[b];
            double dx = ea->X - eb->X, dz = ea->Z - eb->Z;
            if (!(dx * dx + dz * dz < radius * radius)) continue;
            int keep_a = ea->obs_count > eb->obs_count || (ea->obs_count == eb->obs_count && ea->id < eb->id);
            int lose = keep_a ? j : i;
            ent_del_at(m, keep_a ? b : a);
            if (removed_out) removed_out[nr] = ids[lose];
            nr++;
            ids[lose] = 0;
            if (!keep_a) break;   /* entry i is gone; b may have moved in the dense array */
            a = hmap_get(&m->ids, ids[i]);
        }
    }
    /* a new entry (first registration) next to an entry the view did not
     * register duplicates an object already in the map: drop the new one, so
     * the other stays untouched */
    for (int i = 0; radius > 0 && i < k; i++) {
        uint32_t a = ids[i] ? hmap_get(&m->ids, ids[i]) : SOOC_HEMPTY;
        if (a == SOOC_HEMPTY || m->ent[a].obs_count != 1) continue;
        double X = m->ent[a].X, Z = m->ent[a].Z;
        if (!near_other(m, X, Z, radius, ids, k)) continue;
        ent_del_at(m, a);
        if (removed_out) removed_out[nr] = ids[i];
        nr++;
        ids[i] = 0;
    }
    if (n_removed) *n_removed = nr;
}

/* The entry outside ids[0..k) nearest to (X, Z), closer than r; SOOC_HEMPTY if none. */
static uint32_t nearest_other(const sooc_cogmap *m, double X, double Z, double r, const uint64_t *ids, int k) {
    int32_t ci0, cj0, ci1, cj1;
    cell_coords(m, X - r, Z - r, &ci0, &cj0);
    cell_coords(m, X + r, Z + r, &ci1, &cj1);
    uint32_t best = SOOC_HEMPTY;
    double bd = r * r;
    for (int64_t ci = ci0; ci <= ci1; ci++)
        for (int64_t cj = cj0; cj <= cj1; cj++) {
            const sooc_cell *cl = cell_at(m, (int32_t)ci, (int32_t)cj);
            if (!cl) continue;
            for (uint32_t i = 0; i < cl->n; i++) {
                const sooc_cell_member *mb = &cl->mem[i];
                double dx = mb->X - X, dz = mb->Z - Z, d2 = dx * dx + dz * dz;
                if (!(d2 < bd)) continue;
                int listed = 0;
                for (int j = 0; j < k && !listed; j++) listed = ids[j] == mb->id;
                if (listed) continue;
                bd = d2;
                best = mb->idx;
            }
        }
    return best;
}

sooc_status sooc_cogmap_merge_neighbours(sooc_cogmap *m, uint64_t *ids, int k, double radius,
                                         uint64_t *removed_out, int cap, int *n_removed) {
    int nr = 0;
    sooc_status st = SOOC_OK;
    for (int i = 0; radius > 0 && i < k && nr < cap && !st; i++) {
        uint32_t a = ids[i] ? hmap_get(&m->ids, ids[i]) : SOOC_HEMPTY;
        if (a == SOOC_HEMPTY) continue;
        uint32_t b = nearest_other(m, m->ent[a].X, m->ent[a].Z, radius, ids, k);
        if (b == SOOC_HEMPTY) continue;
        const sooc_cogmap_entry ea = m->ent[a], eb = m->ent[b];
        int keep_a = ea.obs_count > eb.obs_count || (ea.obs_count == eb.obs_count && ea.id < eb.id);
        /* two estimates of one object: where and what means are their mean
         * weighted by observation counts (a settled entry is not carried off
         * by a young one); variances and presence are the view's */
        sooc_cogmap_entry kept = ea;
        kept.id = keep_a ? ea.id : eb.id;
        double wb = (double)eb.obs_count / ((double)ea.obs_count + eb.obs_count);
        kept.X = ea.X + wb * (eb.X - ea.X);
        kept.Z = ea.Z + wb * (eb.Z - ea.Z);
        kept.Theta = sooc_wrap_angle(ea.Theta + wb * sooc_wrap_angle(eb.Theta - ea.Theta));
        for (int j = 0; j < ea.dim; j++)
            kept.what_mu[j] = (float)(ea.what_mu[j] + wb * ((double)eb.what_mu[j] - ea.what_mu[j]));
        uint64_t obs = (uint64_t)ea.obs_count + eb.obs_count;
        kept.obs_count = obs > UINT32_MAX ? UINT32_MAX : (uint32_t)obs;
        if (eb.first_seen_ns < kept.first_seen_ns) kept.first_seen_ns = eb.first_seen_ns;
        uint64_t lose = keep_a ? eb.id : ea.id;
        ent_del_at(m, keep_a ? b : a);
        st = ent_put(m, &kept);   /* overwrites an existing id: never appends */
        if (removed_out) removed_out[nr] = lose;
        nr++;
        ids[i] = kept.id;
    }
    if (n_removed) *n_removed = nr;
    return st;
}

/* --------------------------------------------------------- layout blocks */

void sooc_cogmap_block_of(const sooc_cogmap *m, double X, double Z, int32_t *bi, int32_t *bj) {
    double a = floor(X / m->block), b = floor(Z / m->block);
    *bi = (int32_t)(a < -2e9 ? -2e9 : a > 2e9 ? 2e9 : a);
    *bj = (int32_t)(b < -2e9 ? -2e9 : b > 2e9 ? 2e9 : b);
}

void sooc_cogmap_block_origin(const sooc_cogmap *m, int32_t bi, int32_t bj, double *X, double *Z) {
    *X = ((double)bi + 0.5) * m->block;
    *Z = ((double)bj + 0.5) * m->block;
}

sooc_status sooc_cogmap_active_block(const sooc_cogmap *m, const double T_wc[16], double d_clip, int32_t *bi,
                                     int32_t *bj, double origin_local[2]) {
    double T_wg[16];
    sooc_status s = sooc_gframe(T_wc, T_wg, NULL, NULL, NULL);
    if (s) return s;
    sooc_floor_frame f;
    sooc_floor_frame_of(&f, T_wg);
    /* G's z axis in the world is (sin psi, 0, cos psi) */
    double X = f.X + 0.5 * d_clip * sin(f.psi), Z = f.Z + 0.5 * d_clip * cos(f.psi);
    sooc_cogmap_block_of(m, X, Z, bi, bj);
    if (origin_local) {
        double w[3], l[3];
        sooc_cogmap_block_origin(m, *bi, *bj, &w[0], &w[1]);
        w[2] = f.psi;
        sooc_floor_to_local(&f, w, l);
        origin_local[0] = l[0];
        origin_local[1] = l[1];
    }
    return SOOC_OK;
}

sooc_status sooc_cogmap_layout_get(const sooc_cogmap *m, int32_t bi, int32_t bj, float *mu, float *logvar) {
    uint32_t b = m->ldim ? hmap_get(&m->blocks_h, pack2(bi, bj)) : SOOC_HEMPTY;
    if (b == SOOC_HEMPTY)
        return sooc_seterr(SOOC_ENOTFOUND, "cogmap: no layout latent for block (%d, %d)", (int)bi, (int)bj);
    const float *p = m->blk_lat + (size_t)b * 2 * m->ldim;
    if (mu) memcpy(mu, p, (size_t)m->ldim * sizeof(float));
    if (logvar) memcpy(logvar, p + m->ldim, (size_t)m->ldim * sizeof(float));
    return SOOC_OK;
}

sooc_status sooc_cogmap_layout_set(sooc_cogmap *m, int32_t bi, int32_t bj, const float *mu, const float *logvar) {
    if (!m->ldim) return sooc_seterr(SOOC_EINVAL, "cogmap: map has no layout latents (layout_dim = 0)");
    for (int i = 0; i < m->ldim; i++)
        if (!isfinite(mu[i]) || !isfinite(logvar[i]))
            return sooc_seterr(SOOC_ENUMERIC, "cogmap: layout block (%d, %d) latent %d not finite", (int)bi,
                               (int)bj, i);
    uint64_t key = pack2(bi, bj);
    uint32_t b = hmap_get(&m->blocks_h, key);
    if (b == SOOC_HEMPTY) {
        if (m->n_blk == m->cap_blk) {
            size_t nc = m->cap_blk ? m->cap_blk * 2 : 16;
            int32_t *k2 = sooc_realloc(m->blk_key, nc * 2 * sizeof *k2);
            if (!k2) return SOOC_ENOMEM;
            m->blk_key = k2;
            float *l2 = sooc_realloc(m->blk_lat, nc * 2 * (size_t)m->ldim * sizeof *l2);
            if (!l2) return SOOC_ENOMEM;
            m->blk_lat = l2;
            m->cap_blk = nc;
        }
        sooc_status s = hmap_put(&m->blocks_h, key, (uint32_t)m->n_blk);
        if (s) return s;
        b = (uint32_t)m->n_blk++;
        m->blk_key[2 * b] = bi;
        m->blk_key[2 * b + 1] = bj;
    }
    float *p = m->blk_lat + (size_t)b * 2 * m->ldim;
    memcpy(p, mu, (size_t)m->ldim * sizeof(float));
    memcpy(p + m->ldim, logvar, (size_t)m->ldim * sizeof(float));
    return SOOC_OK;
}

size_t sooc_cogmap_layout_count(const sooc_cogmap *m) { return m->n_blk; }

int sooc_cogmap_layout_foreach(const sooc_cogmap *m, sooc_cogmap_block_fn fn, void *user) {
    for (size_t b = 0; b < m->n_blk; b++) {
        const float *p = m->blk_lat + b * 2 * (size_t)m->ldim;
        int r = fn(user, m->blk_key[2 * b], m->blk_key[2 * b + 1], p, p + m->ldim);
        if (r) return r;
    }
    return 0;
}
