/* A tiny stand-in for the model's mapper (tests and bench only): every
 * keyframe registers one new object 1.5 m in front of the camera on the
 * floor, re-observes the object registered before it, and every 5th
 * keyframe removes the oldest remaining object. Deterministic. It reports
 * what changed (sooc_mapper_changed) and keeps a 4-float layout latent per
 * 4 m floor block under the camera. */
#include "sooc3d/mapper.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define FAKE_W 32
#define FAKE_H 24
#define FAKE_DIM 8
#define FAKE_LDIM 4
#define FAKE_MAX_BLOCKS 256

struct sooc_mapper {
    sooc_map_entry *e;
    size_t n, cap;
    uint64_t next_id, updates;
    double delay_ms;
    uint64_t chg[2], rem[1];
    int n_chg, n_rem, has_block;
    int32_t bi, bj;
    struct { int32_t bi, bj; float mu[FAKE_LDIM], lv[FAKE_LDIM]; } blocks[FAKE_MAX_BLOCKS];
    int n_blocks;
};

static int find_block(const sooc_mapper *m, int32_t bi, int32_t bj) {
    for (int i = 0; i < m->n_blocks; i++)
        if (m->blocks[i].bi == bi && m->blocks[i].bj == bj) return i;
    return -1;
}

static sooc_status set_block(sooc_mapper *m, int32_t bi, int32_t bj, const float *mu, const float *lv) {
    int i = find_block(m, bi, bj);
    if (i < 0) {
        if (m->n_blocks == FAKE_MAX_BLOCKS) return sooc_seterr(SOOC_ENOMEM, "fake mapper: too many blocks");
        i = m->n_blocks++;
        m->blocks[i].bi = bi;
        m->blocks[i].bj = bj;
    }
    memcpy(m->blocks[i].mu, mu, sizeof m->blocks[i].mu);
    memcpy(m->blocks[i].lv, lv, sizeof m->blocks[i].lv);
    return SOOC_OK;
}

void sooc_mapper_params_default(sooc_mapper_params *p) { memset(p, 0, sizeof *p); }

sooc_status sooc_mapper_create(sooc_mapper **out, const sooc_mapper_params *p) {
    (void)p;
    sooc_mapper *m = sooc_calloc(1, sizeof *m);
    if (!m) return SOOC_ENOMEM;
    m->next_id = 1;
    const char *d = getenv("SOOC_FAKE_MAPPER_DELAY_MS");
    m->delay_ms = d ? atof(d) : 0.0;
    *out = m;
    return SOOC_OK;
}

void sooc_mapper_destroy(sooc_mapper *m) {
    if (!m) return;
    sooc_free(m->e);
    sooc_free(m);
}

void sooc_mapper_input_size(const sooc_mapper *m, int *w, int *h) {
    (void)m;
    *w = FAKE_W;
    *h = FAKE_H;
}

void sooc_mapper_cam_heights(const sooc_mapper *m, double *lo_m, double *hi_m) {
    (void)m;
    *lo_m = 1.2, *hi_m = 2.0;   /* the unity generator's, as a model without a stored range */
}

static sooc_status push(sooc_mapper *m, const sooc_map_entry *e) {
    if (m->n == m->cap) {
        size_t nc = m->cap ? 2 * m->cap : 16;
        void *q = sooc_realloc(m->e, nc * sizeof *m->e);
        if (!q) return SOOC_ENOMEM;
        m->e = q;
        m->cap = nc;
    }
    m->e[m->n++] = *e;
    return SOOC_OK;
}

sooc_status sooc_mapper_update(sooc_mapper *m, const sooc_frame *f, sooc_update_stats *st) {
    if (!f->has_pose) return sooc_seterr(SOOC_EINVAL, "fake mapper: frame without pose");
    if (f->width != FAKE_W || f->height != FAKE_H)
        return sooc_seterr(SOOC_EINVAL, "fake mapper: frame is %dx%d, want %dx%d", f->width, f->height, FAKE_W,
                           FAKE_H);
    if (m->delay_ms > 0) {
        double t0 = sooc_seconds();
        while ((sooc_seconds() - t0) * 1e3 < m->delay_ms) {
        }
    }
    m->updates++;
    m->n_chg = m->n_rem = m->has_block = 0;
    if (st) memset(st, 0, sizeof *st);
    /* re-observe the newest object */
    if (m->n) {
        m->chg[m->n_chg++] = m->e[m->n - 1].id;
        sooc_map_entry *l = &m->e[m->n - 1];
        l->obs_count++;
        l->last_seen_ns = f->t_ns;
        l->sigma_t *= 0.9;
        if (st) st->n_retrieved = 1;
    }
    /* a new object 1.5 m ahead of the camera, on the floor */
    sooc_map_entry e;
    memset(&e, 0, sizeof e);
    e.id = m->next_id++;
    double fwd[3] = {f->T_wc[2], f->T_wc[6], f->T_wc[10]};
    double nrm = sqrt(fwd[0] * fwd[0] + fwd[2] * fwd[2]);
    if (nrm < 1e-9) nrm = 1;
    e.x = f->T_wc[3] + 1.5 * fwd[0] / nrm;
    e.z = f->T_wc[11] + 1.5 * fwd[2] / nrm;
    e.yaw = 0.1 * (double)e.id;
    e.sigma_t = 0.2;
    e.sigma_yaw = 0.3;
    e.presence_logit = 2.0f;
    e.presence = 1.0f / (1.0f + expf(-2.0f));
    e.latent_dim = FAKE_DIM;
    for (int i = 0; i < FAKE_DIM; i++) {
        e.what_mu[i] = (float)e.id + 0.01f * (float)i;
        e.what_logvar[i] = -1.0f;
    }
    e.extent[0] = 0.4f;
    e.extent[1] = 0.8f;
    e.extent[2] = 0.5f;
    e.first_seen_ns = e.last_seen_ns = f->t_ns;
    e.obs_count = 1;
    sooc_status s = push(m, &e);
    if (s) return s;
    m->chg[m->n_chg++] = e.id;
    if (st) { st->n_registered = 1; st->n_new = 1; }
    if (m->updates % 5 == 0 && m->n > 1) {
        m->rem[m->n_rem++] = m->e[0].id;
        if (m->n_chg && m->chg[0] == m->e[0].id) {   /* removed after its re-observation */
            m->chg[0] = m->chg[1];
            m->n_chg--;
        }
        memmove(m->e, m->e + 1, (m->n - 1) * sizeof *m->e);
        m->n--;
        if (st) st->n_removed = 1;
    }
    /* layout latent of the block under the camera */
    int32_t bi = (int32_t)floor(f->T_wc[3] / 4.0), bj = (int32_t)floor(f->T_wc[11] / 4.0);
    float mu[FAKE_LDIM], lv[FAKE_LDIM];
    for (int i = 0; i < FAKE_LDIM; i++) {
        mu[i] = (float)m->updates + 0.1f * (float)i;
        lv[i] = -2.0f;
    }
    if ((s = set_block(m, bi, bj, mu, lv))) return s;
    m->has_block = 1;
    m->bi = bi;
    m->bj = bj;
    return SOOC_OK;
}

static const sooc_map_entry *find_entry(const sooc_mapper *m, uint64_t id) {
    for (size_t i = m->n; i-- > 0;)
        if (m->e[i].id == id) return &m->e[i];
    return NULL;
}

sooc_status sooc_mapper_changed(const sooc_mapper *m, sooc_map_entry *out, size_t cap, size_t *n,
                                  uint64_t *removed_ids, size_t cap_r, size_t *n_removed) {
    if (n) *n = (size_t)m->n_chg;
    if (n_removed) *n_removed = (size_t)m->n_rem;
    if ((out && (size_t)m->n_chg > cap) || (removed_ids && (size_t)m->n_rem > cap_r))
        return sooc_seterr(SOOC_EINVAL, "fake mapper: changed arrays too small");
    for (int i = 0; out && i < m->n_chg; i++) {
        const sooc_map_entry *e = find_entry(m, m->chg[i]);
        if (!e) return sooc_seterr(SOOC_ENOTFOUND, "fake mapper: changed id %llu missing", (unsigned long long)m->chg[i]);
        out[i] = *e;
    }
    for (int i = 0; removed_ids && i < m->n_rem; i++) removed_ids[i] = m->rem[i];
    return SOOC_OK;
}

int sooc_mapper_latent_dim(const sooc_mapper *m) {
    (void)m;
    return FAKE_DIM;
}

int sooc_mapper_layout_dim(const sooc_mapper *m) {
    (void)m;
    return FAKE_LDIM;
}

sooc_status sooc_mapper_last_layout(const sooc_mapper *m, int32_t *bi, int32_t *bj, float *mu, float *logvar) {
    if (!m->has_block) return SOOC_ENOTFOUND;
    int i = find_block(m, m->bi, m->bj);
    if (i < 0) return SOOC_ENOTFOUND;
    *bi = m->bi;
    *bj = m->bj;
    memcpy(mu, m->blocks[i].mu, sizeof m->blocks[i].mu);
    memcpy(logvar, m->blocks[i].lv, sizeof m->blocks[i].lv);
    return SOOC_OK;
}

sooc_status sooc_mapper_load_layout(sooc_mapper *m, int32_t bi, int32_t bj, const float *mu,
                                      const float *logvar) {
    return set_block(m, bi, bj, mu, logvar);
}

/* Test hook: the layout latent of block (bi, bj). */
int fake_mapper_get_block(const sooc_mapper *m, int32_t bi, int32_t bj, float *mu);
int fake_mapper_get_block(const sooc_mapper *m, int32_t bi, int32_t bj, float *mu) {
    int i = find_block(m, bi, bj);
    if (i < 0) return -1;
    memcpy(mu, m->blocks[i].mu, sizeof m->blocks[i].mu);
    return 0;
}

sooc_status sooc_mapper_clear(sooc_mapper *m) {
    m->n = 0;
    m->n_blocks = 0;
    m->n_chg = m->n_rem = m->has_block = 0;
    return SOOC_OK;
}

void sooc_mapper_reserve_ids(sooc_mapper *m, uint64_t next_id) {
    if (next_id > m->next_id) m->next_id = next_id;
}

uint64_t sooc_mapper_next_id(const sooc_mapper *m) { return m->next_id; }

sooc_status sooc_mapper_entries(const sooc_mapper *m, sooc_map_entry *out, size_t cap, size_t *n) {
    *n = m->n;
    if (out)
        for (size_t i = 0; i < m->n && i < cap; i++) out[i] = m->e[i];
    return SOOC_OK;
}

sooc_status sooc_mapper_load_entries(sooc_mapper *m, const sooc_map_entry *e, size_t n) {
    m->n = 0;
    m->n_chg = m->n_rem = m->has_block = 0;
    for (size_t i = 0; i < n; i++) {
        sooc_status s = push(m, &e[i]);
        if (s) return s;
        if (e[i].id >= m->next_id) m->next_id = e[i].id + 1;
    }
    return SOOC_OK;
}

/* The fake mapper keeps no geometry: geometric support is accepted and has no
 * effect (a launch file's model.geo_support_m parses and runs). */
sooc_status sooc_mapper_set_support(sooc_mapper *m, double margin_m) {
    (void)m, (void)margin_m;
    return SOOC_OK;
}

/* Observed-surface boxes need the support's clusters: accepted, no effect. */
void sooc_mapper_set_surface_boxes(sooc_mapper *m, int on) { (void)m, (void)on; }

/* Proposals need clusters the fake mapper does not keep: accepted, no effect. */
void sooc_proposal_params_default(sooc_proposal_params *p) { memset(p, 0, sizeof *p); }
sooc_status sooc_mapper_set_proposals(sooc_mapper *m, const sooc_proposal_params *p) {
    (void)m, (void)p;
    return SOOC_OK;
}
