/* Per-entry and per-layout-block float payloads of a cognitive map (cogmap.h
 * "payloads"): the finetuned decoders (include/sooc3d/train.h).
 * A small array searched linearly: payloads exist only for finetuned objects
 * and blocks, and a field looks up at most 64 ids per view. */
#include "cogmap/cogmap_impl.h"

#include <string.h>

typedef struct pl_rec {
    int is_block;
    uint64_t id;
    int32_t bi, bj;
    float *v;
    size_t n;
} pl_rec;

struct sooc_cogmap_payloads {
    pl_rec *r;
    size_t n, cap;
};

void sooc_cogmap_payloads_free(sooc_cogmap *m) {
    if (!m->pl) return;
    for (size_t i = 0; i < m->pl->n; i++) sooc_free(m->pl->r[i].v);
    sooc_free(m->pl->r);
    sooc_free(m->pl);
    m->pl = NULL;
}

static pl_rec *find(const sooc_cogmap *m, int is_block, uint64_t id, int32_t bi, int32_t bj) {
    if (!m->pl) return NULL;
    for (size_t i = 0; i < m->pl->n; i++) {
        pl_rec *r = &m->pl->r[i];
        if (r->is_block != is_block) continue;
        if (is_block ? (r->bi == bi && r->bj == bj) : r->id == id) return r;
    }
    return NULL;
}

static sooc_status put(sooc_cogmap *m, int is_block, uint64_t id, int32_t bi, int32_t bj, const float *v, size_t n) {
    pl_rec *r = find(m, is_block, id, bi, bj);
    if (!n) {   /* remove */
        if (r) {
            sooc_free(r->v);
            *r = m->pl->r[--m->pl->n];
        }
        return SOOC_OK;
    }
    if (!v) return sooc_seterr(SOOC_EINVAL, "cogmap payload: NULL values");
    for (size_t i = 0; i < n; i++)
        if (!(v[i] == v[i]) || v[i] - v[i] != 0)
            return sooc_seterr(SOOC_ENUMERIC, "cogmap payload: non-finite value at %zu", i);
    float *c = sooc_malloc(n * sizeof(float));
    if (!c) return SOOC_ENOMEM;
    memcpy(c, v, n * sizeof(float));
    if (r) {
        sooc_free(r->v);
        r->v = c, r->n = n;
        return SOOC_OK;
    }
    if (!m->pl) {
        m->pl = sooc_calloc(1, sizeof *m->pl);
        if (!m->pl) {
            sooc_free(c);
            return SOOC_ENOMEM;
        }
    }
    if (m->pl->n == m->pl->cap) {
        size_t nc = m->pl->cap ? 2 * m->pl->cap : 16;
        pl_rec *nr = sooc_realloc(m->pl->r, nc * sizeof *nr);
        if (!nr) {
            sooc_free(c);
            return SOOC_ENOMEM;
        }
        m->pl->r = nr, m->pl->cap = nc;
    }
    pl_rec *nw = &m->pl->r[m->pl->n++];
    nw->is_block = is_block, nw->id = id, nw->bi = bi, nw->bj = bj, nw->v = c, nw->n = n;
    return SOOC_OK;
}

sooc_status sooc_cogmap_payload_set(sooc_cogmap *m, uint64_t id, const float *v, size_t n) {
    if (!id) return sooc_seterr(SOOC_EINVAL, "cogmap payload: id 0");
    return put(m, 0, id, 0, 0, v, n);
}

const float *sooc_cogmap_payload_get(const sooc_cogmap *m, uint64_t id, size_t *n) {
    pl_rec *r = find(m, 0, id, 0, 0);
    if (n) *n = r ? r->n : 0;
    return r ? r->v : NULL;
}

sooc_status sooc_cogmap_block_payload_set(sooc_cogmap *m, int32_t bi, int32_t bj, const float *v, size_t n) {
    return put(m, 1, 0, bi, bj, v, n);
}

const float *sooc_cogmap_block_payload_get(const sooc_cogmap *m, int32_t bi, int32_t bj, size_t *n) {
    pl_rec *r = find(m, 1, 0, bi, bj);
    if (n) *n = r ? r->n : 0;
    return r ? r->v : NULL;
}

size_t sooc_cogmap_payload_count(const sooc_cogmap *m) { return m->pl ? m->pl->n : 0; }

int sooc_cogmap_payload_foreach(const sooc_cogmap *m, sooc_cogmap_payload_fn fn, void *user) {
    if (!m->pl) return 0;
    for (size_t i = 0; i < m->pl->n; i++) {
        const pl_rec *r = &m->pl->r[i];
        int rc = fn(user, r->is_block, r->id, r->bi, r->bj, r->v, r->n);
        if (rc) return rc;
    }
    return 0;
}
