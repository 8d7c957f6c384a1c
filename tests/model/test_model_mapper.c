/* Online mapper and model IO: checkpoint round trip (bit-exact parameters,
 * trainer blob, corrupt-file detection), mapper determinism for a seed,
 * entries/load_entries round trip, registration and retrieval across views,
 * and the render.h field adapter (a dense render from the map is finite and
 * culls: the field's box is honoured). */
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "check.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "synth.h"

static void small_cfg(sooc_model_config *c) {
    sooc_model_config_default(c);
    c->K = 4, c->d_what = 8, c->d_layout = 4, c->L = 2;
    c->img_w = c->img_h = 32, c->ray_w = c->ray_h = 16;
    c->dec_width = 16, c->dec_color_width = 8;
    c->ref_ch[0] = 4, c->ref_ch[1] = 4, c->ref_ch[2] = 8, c->ref_ch[3] = 8;
    c->ref_fc = 16, c->ref_hidden = 16;
    c->prior_pres_logit = 1.0f;
}

static int run_seq_l(const char *path, uint64_t seed, int latents, int slots, sooc_map_entry *out, size_t cap,
                     size_t *n, sooc_mapper **keep) {
    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.model_path = path;
    p.seed = seed;
    p.latents = latents;
    p.slots = slots;
    p.threads = 2;
    sooc_mapper *mp;
    CHECK_OK(sooc_mapper_create(&mp, &p));
    int w, h;
    sooc_mapper_input_size(mp, &w, &h);
    CHECK(w == 32 && h == 32);
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    int retrieved = 0;
    for (int i = 0; i < 5; i++) {
        double T[16];
        synth_pose(T, 0.1 * i, 1.5, 0.1 * i, 0.05 * i, -0.45);
        sooc_frame f;
        CHECK_OK(synth_frame(&f, 32, 32, 60, T, sp, 2));
        f.index = i, f.t_ns = 1000 * i;
        sooc_update_stats st;
        CHECK_OK(sooc_mapper_update(mp, &f, &st));
        if (i) retrieved += st.n_retrieved;
        sooc_frame_free(&f);
    }
    CHECK_OK(sooc_mapper_entries(mp, out, cap, n));
    if (keep)
        *keep = mp;
    else
        sooc_mapper_destroy(mp);
    return retrieved;
}

/* One update from the first camera pose of a frame showing one sphere 3 m ahead. */
static void update_one_sphere(sooc_mapper *mp, int index, sooc_update_stats *us) {
    double T[16];
    synth_pose(T, 0, 1.5, 0, 0, -0.45);
    synth_sphere sp1 = {{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}};
    sooc_frame fr;
    CHECK_OK(synth_frame(&fr, 32, 32, 60, T, &sp1, 1));
    fr.index = index, fr.t_ns = 1000 * (int64_t)index;
    CHECK_OK(sooc_mapper_update(mp, &fr, us));
    sooc_frame_free(&fr);
}

static int cmp_float(const void *a, const void *b) {
    float x = *(const float *)a, y = *(const float *)b;
    return (x > y) - (x < y);
}

static int run_seq(const char *path, uint64_t seed, sooc_map_entry *out, size_t cap, size_t *n, sooc_mapper **keep) {
    return run_seq_l(path, seed, SOOC_LATENTS_MEAN, 0, out, cap, n, keep);
}

/* The shared map entry <-> cogmap entry converters (mapper.h): round trip,
 * extent from the caller, obs_count >= 1 and last_view = -1 in the cogmap. */
static void test_entry_convert(void) {
    sooc_map_entry e, back;
    memset(&e, 0, sizeof e);
    e.id = 42, e.x = 1.5, e.z = -2.25, e.yaw = 0.5, e.sigma_t = 0.25, e.sigma_yaw = 0.125;
    e.presence_logit = 2.0f, e.latent_dim = 4;
    for (int i = 0; i < 4; i++) e.what_mu[i] = 0.5f * (float)i, e.what_logvar[i] = -1.0f - (float)i;
    e.first_seen_ns = 10, e.last_seen_ns = 20, e.obs_count = 0;
    sooc_cogmap_entry ce;
    sooc_map_entry_to_cogmap(&e, &ce);
    CHECK(ce.id == 42 && ce.X == 1.5 && ce.Z == -2.25 && ce.Theta == 0.5 && ce.dim == 4);
    CHECK(ce.obs_count == 1 && ce.last_view == -1 && ce.first_seen_ns == 10 && ce.last_seen_ns == 20);
    CHECK_CLOSE(ce.rho_t, 2 * log(0.25), 1e-6, 0);
    const float ext[3] = {1.2f, 1.0f, 1.2f};
    sooc_map_entry_from_cogmap(&ce, ext, &back);
    CHECK(back.id == 42 && back.x == 1.5 && back.latent_dim == 4 && back.obs_count == 1);
    CHECK_CLOSE(back.sigma_t, 0.25, 1e-6, 0);
    CHECK_CLOSE(back.sigma_yaw, 0.125, 1e-6, 0);
    CHECK_CLOSE(back.presence, 1.0 / (1.0 + exp(-2.0)), 1e-6, 0);
    CHECK(memcmp(back.what_logvar, e.what_logvar, 4 * sizeof(float)) == 0);
    CHECK(back.extent[0] == 1.2f && back.extent[1] == 1.0f && back.extent[2] == 1.2f);
    sooc_map_entry_from_cogmap(&ce, NULL, &back);
    CHECK(back.extent[0] == 0 && back.extent[1] == 0);
    e.sigma_t = 0; /* floored at 1e-12, never log(0) */
    sooc_map_entry_to_cogmap(&e, &ce);
    CHECK(isfinite(ce.rho_t));
}

/* Slots at inference (sooc_model_copy_slots, mapper slots): the copy keeps
 * every weight and learnt prior, adds mirror images (x -> -x) of learnt
 * priors nearest the median depth (in slot order), rejects fewer slots than trained or more than
 * SOOC_MODEL_K_MAX; a mapper asked for the model's own K maps bit-identically,
 * and one with more slots retrieves that many in-view entries. */
static void test_slots(sooc_model *m, const char *path, const sooc_map_entry *e_ref, size_t n_ref) {
    const sooc_model_config *c = sooc_model_get_config(m);
    int K0 = c->K, K = K0 + 2;
    sooc_model *w = NULL;
    CHECK(sooc_model_copy_slots(m, K0 - 1, &w) == SOOC_EINVAL && !w);
    printf("slots %d: %s\n", K0 - 1, sooc_errmsg());
    CHECK(sooc_model_copy_slots(m, SOOC_MODEL_K_MAX + 1, &w) == SOOC_EINVAL && !w);
    CHECK_OK(sooc_model_copy_slots(m, 0, &w));
    CHECK(sooc_model_param_count(w) == sooc_model_param_count(m));
    CHECK(!memcmp(sooc_model_params(w), sooc_model_params(m), sooc_model_param_count(m) * sizeof(float)));
    sooc_model_destroy(w);
    CHECK_OK(sooc_model_copy_slots(m, K, &w));
    CHECK(sooc_model_get_config(w)->K == K);
    sooc_model_tensor ta[64], tb[64];
    int na = sooc_model_tensors(m, ta, 64), nb = sooc_model_tensors(w, tb, 64);
    CHECK(na == nb);
    const float *pa = sooc_model_params(m), *pb = sooc_model_params(w);
    for (int i = 0; i < na && i < nb; i++) {
        CHECK(!strcmp(ta[i].name, tb[i].name));
        if (strcmp(ta[i].name, "prior.slots")) {
            CHECK(ta[i].count == tb[i].count && !memcmp(pa + ta[i].offset, pb + tb[i].offset, ta[i].count * sizeof(float)));
            continue;
        }
        int NL = ta[i].cols;
        const float *la = pa + ta[i].offset, *lb = pb + tb[i].offset;
        CHECK(tb[i].rows == K && !memcmp(la, lb, (size_t)K0 * NL * sizeof(float)));
        /* the learnt priors' depths, and the one nearest their median */
        float zs[16];
        for (int k = 0; k < K0; k++) zs[k] = la[k * NL + 1];
        qsort(zs, (size_t)K0, sizeof zs[0], cmp_float);
        float med = zs[(K0 - 1) / 2], dmax = 0;
        int chosen[16] = {0}, prev = -1;
        for (int k = K0; k < K; k++) {
            int src = -1;
            for (int j = 0; j < K0 && src < 0; j++)
                if (lb[k * NL] == -la[j * NL] && !memcmp(lb + k * NL + 1, la + j * NL + 1, (size_t)(NL - 1) * sizeof(float)))
                    src = j;
            CHECK_MSG(src >= 0, "added prior %d is not a mirrored learnt prior", k);
            if (src < 0) continue;
            CHECK_MSG(src > prev, "added priors not distinct and in slot order: %d after %d", src, prev);
            prev = src;
            chosen[src] = 1;
            dmax = fmaxf(dmax, fabsf(la[src * NL + 1] - med));
            printf("slot %d: mirror of learnt prior %d (x %.2f z %.2f)\n", k, src, lb[k * NL], lb[k * NL + 1]);
        }
        /* middle-out: the mirrored ones are the learnt priors nearest the median depth */
        for (int j = 0; j < K0; j++)
            if (!chosen[j]) CHECK_MSG(fabsf(la[j * NL + 1] - med) >= dmax, "prior %d nearer the median, not chosen", j);
        for (int j = 0; j < K0; j++)
            if (la[j * NL + 1] == med) CHECK_MSG(chosen[j], "the median-depth prior is not mirrored");
    }
    sooc_model_destroy(w);
    /* the mapper: its own K is the default; more slots retrieve more entries */
    static sooc_map_entry e[256];
    size_t n;
    run_seq_l(path, 7, SOOC_LATENTS_MEAN, K0, e, 256, &n, NULL);
    CHECK(n == n_ref && !memcmp(e, e_ref, n * sizeof e[0]));
    for (int pass = 0; pass < 2; pass++) {
        sooc_mapper_params p;
        sooc_mapper_params_default(&p);
        p.model_path = path, p.threads = 2, p.slots = pass ? K : 0;
        sooc_mapper *mp;
        CHECK_OK(sooc_mapper_create(&mp, &p));
        CHECK(sooc_model_get_config(sooc_mapper_model(mp))->K == (pass ? K : K0));
        sooc_map_entry ent[8];
        for (int i = 0; i < 8; i++) {   /* 8 entries in front of the camera */
            memcpy(&ent[i], e_ref, sizeof ent[i]);
            ent[i].id = 100 + (uint64_t)i, ent[i].x = -0.9 + 0.25 * i, ent[i].z = 2.5 + 0.1 * i;
            ent[i].presence_logit = 4.0f - 0.1f * (float)i;
            ent[i].presence = 1.0f / (1.0f + expf(-ent[i].presence_logit));
        }
        CHECK_OK(sooc_mapper_load_entries(mp, ent, 8));
        sooc_update_stats us;
        update_one_sphere(mp, 1, &us);
        printf("mapper with %d slots: retrieved %d of 8 in-view entries\n", pass ? K : K0, us.n_retrieved);
        CHECK(us.n_retrieved == (pass ? K : K0));
        sooc_mapper_destroy(mp);
    }
    /* a checkpoint that carries its inference slot count: the mapper uses it
     * unless told otherwise */
    {
        char ps[160];
        snprintf(ps, sizeof ps, "%s.slots", path);
        sooc_model *ms;
        CHECK_OK(sooc_model_copy_slots(m, 0, &ms));
        CHECK_OK(sooc_model_set_slots(ms, K));
        CHECK_OK(sooc_model_save(ms, ps, NULL, 0));
        sooc_model_destroy(ms);
        for (int ask = 0; ask <= K0; ask += K0) {
            sooc_mapper_params q;
            sooc_mapper_params_default(&q);
            q.model_path = ps, q.slots = ask;
            sooc_mapper *mq;
            CHECK_OK(sooc_mapper_create(&mq, &q));
            CHECK(sooc_model_get_config(sooc_mapper_model(mq))->K == (ask ? K0 : K));
            sooc_mapper_destroy(mq);
        }
        remove(ps);
    }
    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.model_path = path, p.slots = K0 - 1;
    sooc_mapper *bad = NULL;
    CHECK(sooc_mapper_create(&bad, &p) == SOOC_EINVAL && !bad);
    CHECK_MSG(strstr(sooc_errmsg(), path) != NULL, "error does not name the model file: %s", sooc_errmsg());
}

/* Non-zero refinement heads (they start at zero), so that updates move the slots. */
static void nonzero_heads(sooc_model *m) {
    sooc_model_tensor t[64];
    int nt = sooc_model_tensors(m, t, 64);
    sooc_rng r;
    sooc_rng_seed(&r, 1, 0);
    for (int i = 0; i < nt; i++)
        if (strstr(t[i].name, "head.W"))
            for (size_t j = 0; j < t[i].count; j++) sooc_model_params(m)[t[i].offset + j] = 0.01f * (float)sooc_rng_normal(&r);
}

/* Five views of the two-sphere scene at w x h through a mapper around model m
 * (owned by the mapper); the final entries. */
static void run_seq_model(sooc_model *m, int w, int h, sooc_map_entry *out, size_t cap, size_t *n) {
    sooc_mapper *mp;
    CHECK_OK(sooc_mapper_create_with_model(&mp, m, 0, 7, 2));
    synth_sphere sp[2] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}}};
    for (int i = 0; i < 5; i++) {
        double T[16];
        synth_pose(T, 0.1 * i, 1.5, 0.1 * i, 0.05 * i, -0.45);
        sooc_frame f;
        CHECK_OK(synth_frame(&f, w, h, 60, T, sp, 2));
        f.index = i, f.t_ns = 1000 * i;
        sooc_update_stats st;
        CHECK_OK(sooc_mapper_update(mp, &f, &st));
        sooc_frame_free(&f);
    }
    *n = 0;
    CHECK_OK(sooc_mapper_entries(mp, out, cap, n));
    sooc_mapper_destroy(mp);
}

/* Ray grid (sooc_model_copy_rays): above 32 x 32 the refinement nets pool
 * their last conv map to a 32 x 32 grid's 2 x 2, so a model trained on the
 * 32 x 32 sub-grid of 64 x 64 frames runs on every pixel with the same
 * weights, deterministically, and maps differently. Grids of 16 and 32 have
 * different FC sizes: that copy is refused. */
static void test_rays(const sooc_model *m) {
    sooc_model *w = NULL;
    CHECK(sooc_model_copy_rays(m, 24, 24, &w) == SOOC_EINVAL && !w);   /* not a multiple of 16 */
    printf("rays 24: %s\n", sooc_errmsg());
    CHECK(sooc_model_copy_rays(m, 32, 32, &w) == SOOC_EINVAL && !w);   /* 16 -> 32: another FC size */
    printf("rays 16 -> 32: %s\n", sooc_errmsg());
    sooc_model_config c = *sooc_model_get_config(m);
    c.img_w = c.img_h = 64, c.ray_w = c.ray_h = 32;
    sooc_model *b;
    CHECK_OK(sooc_model_create(&b, &c, 3));
    /* the FC of both refinement nets (objects, layout) reads a 2 x 2 map instead of 1 x 1 */
    CHECK(sooc_model_param_count(b) == sooc_model_param_count(m) + (size_t)2 * 3 * c.ref_ch[3] * c.ref_fc);
    nonzero_heads(b);
    CHECK(sooc_model_copy_rays(b, 48, 48, &w) == SOOC_EINVAL && !w);   /* above 32: multiples of 32 */
    printf("rays 48: %s\n", sooc_errmsg());
    CHECK(sooc_model_copy_rays(b, 128, 128, &w) == SOOC_EINVAL && !w);  /* does not divide 64 */
    sooc_model *w1 = NULL, *w2 = NULL, *b2 = NULL;
    CHECK_OK(sooc_model_copy_rays(b, 64, 64, &w1));
    CHECK_OK(sooc_model_copy_rays(b, 64, 64, &w2));
    CHECK_OK(sooc_model_copy_rays(b, 32, 32, &b2));
    const sooc_model_config *cw = sooc_model_get_config(w1);
    CHECK(cw->ray_w == 64 && cw->ray_h == 64 && cw->K == c.K && cw->img_w == 64);
    CHECK(sooc_model_param_count(w1) == sooc_model_param_count(b));
    CHECK(!memcmp(sooc_model_params(w1), sooc_model_params(b), sooc_model_param_count(b) * sizeof(float)));
    static sooc_map_entry e32[256], e64[256], e64b[256];
    size_t n32 = 0, n64 = 0, n64b = 0;
    run_seq_model(b2, 64, 64, e32, 256, &n32);
    run_seq_model(w1, 64, 64, e64, 256, &n64);
    run_seq_model(w2, 64, 64, e64b, 256, &n64b);
    printf("64x64 frames: %zu entries on the 32x32 sub-grid, %zu on every pixel\n", n32, n64);
    CHECK(n64 >= 1 && n64 == n64b && !memcmp(e64, e64b, n64 * sizeof e64[0]));
    CHECK(n64 != n32 || memcmp(e64, e32, n64 * sizeof e64[0]));
    for (size_t i = 0; i < n64; i++) CHECK(isfinite(e64[i].x) && isfinite(e64[i].z) && isfinite(e64[i].presence));
    sooc_model_destroy(b);
}

int main(void) {
    test_entry_convert();
    sooc_model_config c;
    small_cfg(&c);
    sooc_model *m;
    CHECK_OK(sooc_model_create(&m, &c, 3));
    nonzero_heads(m);
    char path[128];
    snprintf(path, sizeof path, "/tmp/test_model_mapper.%d.bin", (int)getpid());
    const char blob[] = "trainer-state";
    CHECK_OK(sooc_model_save(m, path, blob, sizeof blob));
    sooc_model *m2;
    void *b2;
    size_t bn;
    CHECK_OK(sooc_model_load(&m2, path, &b2, &bn));
    CHECK(bn == sizeof blob && b2 && !memcmp(b2, blob, bn));
    CHECK(sooc_model_param_count(m2) == sooc_model_param_count(m));
    CHECK(!memcmp(sooc_model_params(m2), sooc_model_params(m), sooc_model_param_count(m) * sizeof(float)));
    CHECK(!memcmp(sooc_model_get_config(m2), &c, sizeof c));
    sooc_free(b2);
    sooc_model_destroy(m2);
    /* corrupt copy -> EFORMAT */
    {
        void *buf;
        size_t n;
        CHECK_OK(sooc_file_read_all(path, 1 << 28, &buf, &n));
        ((uint8_t *)buf)[n / 2] ^= 0x40;
        char bad[160];
        snprintf(bad, sizeof bad, "%s.bad", path);
        CHECK_OK(sooc_file_write_atomic(bad, buf, n));
        CHECK(sooc_model_load(&m2, bad, NULL, NULL) == SOOC_EFORMAT);
        remove(bad);
        sooc_free(buf);
    }
    /* a version-2 file (config without the appended slots field: the shipped
     * models of sessions 1-5) loads, with slots 0 and the same parameters */
    {
        sooc_model *m3;
        CHECK_OK(sooc_model_create(&m3, &c, 3));
        CHECK_OK(sooc_model_set_slots(m3, c.K + 2));
        CHECK(sooc_model_set_slots(m3, c.K - 1) == SOOC_EINVAL && sooc_model_get_config(m3)->slots == c.K + 2);
        memcpy(sooc_model_params(m3), sooc_model_params(m), sooc_model_param_count(m) * sizeof(float));
        char p3[160];
        snprintf(p3, sizeof p3, "%s.v3", path);
        CHECK_OK(sooc_model_save(m3, p3, NULL, 0));
        void *buf;
        size_t n;
        CHECK_OK(sooc_file_read_all(p3, 1 << 28, &buf, &n));
        uint8_t *b3 = buf;
        uint32_t csz3, csz2 = (uint32_t)offsetof(sooc_model_config, slots), ver2 = 2;
        memcpy(&csz3, b3 + 12, 4);
        CHECK(csz3 == sizeof(sooc_model_config) && csz3 > csz2);
        size_t n2 = n - (csz3 - csz2);
        uint8_t *b2 = malloc(n2);
        memcpy(b2, b3, 16 + csz2);
        memcpy(b2 + 8, &ver2, 4);
        memcpy(b2 + 12, &csz2, 4);
        memcpy(b2 + 16 + csz2, b3 + 16 + csz3, n - 16 - csz3 - 4);
        uint32_t crc = sooc_crc32(0, b2, n2 - 4);
        memcpy(b2 + n2 - 4, &crc, 4);
        CHECK_OK(sooc_file_write_atomic(p3, b2, n2));
        sooc_model *mv2 = NULL;
        CHECK_OK(sooc_model_load(&mv2, p3, NULL, NULL));
        CHECK(mv2 && sooc_model_get_config(mv2)->slots == 0 && sooc_model_get_config(mv2)->K == c.K);
        CHECK(mv2 && !memcmp(sooc_model_params(mv2), sooc_model_params(m), sooc_model_param_count(m) * sizeof(float)));
        sooc_model_destroy(mv2);
        free(b2);
        sooc_free(buf);
        remove(p3);
        sooc_model_destroy(m3);
    }
    /* fuzz reproducers (tests/fuzz/crashes/model_ckpt): every one must fail cleanly */
    {
        static const char *fz[] = {"int_overflow_model_c114.ckpt", "int_overflow_model_c83.ckpt",
                                   "oom_unbounded_config_model_c198.ckpt", "overread_config_model_c307.ckpt",
                                   "overread_np_model_c309.ckpt"};
        const char *src = getenv("SOOC_SRC") ? getenv("SOOC_SRC") : ".";
        for (size_t i = 0; i < sizeof fz / sizeof fz[0]; i++) {
            char fp[512];
            snprintf(fp, sizeof fp, "%s/tests/fuzz/crashes/model_ckpt/%s", src, fz[i]);
            if (!sooc_file_exists(fp)) continue;
            sooc_model *mz = NULL;
            sooc_status sz = sooc_model_load(&mz, fp, NULL, NULL);
            CHECK_MSG(sz != SOOC_OK && mz == NULL, "%s loaded", fz[i]);
            printf("fuzz %s -> %s: %s\n", fz[i], sooc_status_str(sz), sooc_errmsg());
        }
    }
    /* mapper: deterministic for a seed, registration and retrieval */
    static sooc_map_entry e1[256], e2[256], e3[256];
    size_t n1, n2, n3;
    sooc_mapper *mp;
    int ret = run_seq(path, 7, e1, 256, &n1, &mp);
    run_seq(path, 7, e2, 256, &n2, NULL);
    printf("mapper: %zu entries after 5 views, %d slots retrieved over views 2..5\n", n1, ret);
    CHECK(n1 >= 1 && ret >= 1);
    CHECK(n1 == n2 && !memcmp(e1, e2, n1 * sizeof e1[0]));
    for (size_t i = 1; i < n1; i++) CHECK(e1[i].id > e1[i - 1].id);
    /* latents: refining on posterior samples (as in training) is deterministic
     * for a seed too, and differs from refining on the means (the default) */
    {
        static sooc_map_entry s1[256], s2[256];
        size_t m1, m2;
        run_seq_l(path, 7, SOOC_LATENTS_SAMPLE, 0, s1, 256, &m1, NULL);
        run_seq_l(path, 7, SOOC_LATENTS_SAMPLE, 0, s2, 256, &m2, NULL);
        CHECK(m1 == m2 && !memcmp(s1, s2, m1 * sizeof s1[0]));
        int differ = m1 != n1;
        for (size_t i = 0; i < m1 && i < n1 && !differ; i++) differ = s1[i].x != e1[i].x || s1[i].z != e1[i].z;
        CHECK_MSG(differ, "sampled and mean refinement give the same map");
    }
    test_slots(m, path, e1, n1);
    test_rays(m);
    /* load_entries round trip */
    CHECK_OK(sooc_mapper_load_entries(mp, e1, n1));
    CHECK_OK(sooc_mapper_entries(mp, e3, 256, &n3));
    CHECK(n3 == n1);
    for (size_t i = 0; i < n3 && i < n1; i++) {
        CHECK(e3[i].id == e1[i].id);
        CHECK_CLOSE(e3[i].x, e1[i].x, 1e-9, 0);
        CHECK_CLOSE(e3[i].sigma_t, e1[i].sigma_t, 1e-5, 1e-5);
        CHECK(!memcmp(e3[i].what_mu, e1[i].what_mu, sizeof e1[i].what_mu));
    }
    /* duplicate merge: two entries 0.11 m apart in front of the camera. The
     * untrained refinement leaves them where they are (its last layer starts
     * at zero), so both are retrieved and registered; the better-observed one
     * stays and the other is reported removed, not changed. Off: both stay. */
    for (int pass = 0; pass < 2; pass++) {
        sooc_map_entry dup[2];
        memcpy(dup, e1, sizeof dup[0]);
        memcpy(dup + 1, e1, sizeof dup[0]);
        dup[0].id = 40, dup[0].x = 0.3, dup[0].z = 3.0, dup[0].obs_count = 1;
        dup[1].id = 41, dup[1].x = 0.4, dup[1].z = 3.05, dup[1].obs_count = 2;
        dup[0].presence_logit = dup[1].presence_logit = 4.0f;
        dup[0].presence = dup[1].presence = 1.0f / (1.0f + expf(-4.0f));
        CHECK_OK(sooc_mapper_load_entries(mp, dup, 2));
        sooc_mapper_set_merge_radius(mp, pass ? 0.0 : SOOC_MAPPER_MERGE_SUGGESTED);   /* 0.35 m, then off */
        sooc_update_stats us;
        update_one_sphere(mp, 9, &us);
        sooc_map_entry chg[SOOC_MAPPER_CHANGED_MAX];
        uint64_t rm[SOOC_MAPPER_CHANGED_MAX];
        size_t nc, nrm;
        CHECK_OK(sooc_mapper_changed(mp, chg, SOOC_MAPPER_CHANGED_MAX, &nc, rm, SOOC_MAPPER_CHANGED_MAX, &nrm));
        CHECK_OK(sooc_mapper_entries(mp, e3, 256, &n3));
        int has40 = 0, has41 = 0, chg40 = 0, rm40 = 0;
        for (size_t i = 0; i < n3; i++) has40 |= e3[i].id == 40, has41 |= e3[i].id == 41;
        for (size_t i = 0; i < nc; i++) chg40 |= chg[i].id == 40;
        for (size_t i = 0; i < nrm; i++) rm40 |= rm[i] == 40;
        printf("merge %s: retrieved %d, registered %d, merged %d, removed %zu, %zu entries\n", pass ? "off" : "on",
               us.n_retrieved, us.n_registered, us.n_merged, nrm, n3);
        CHECK(us.n_retrieved == 2 && has41);
        CHECK(nrm == (size_t)(us.n_removed + us.n_merged));
        if (!pass) CHECK(us.n_merged >= 1 && !has40 && rm40 && !chg40 && n3 == (size_t)us.n_registered - us.n_merged);
        else CHECK(us.n_merged == 0 && has40 && !rm40 && chg40);
    }
    /* field adapter: render the first view from the map */
    double T[16];
    synth_pose(T, 0, 1.5, 0, 0, -0.45);
    sooc_intrinsics K;
    memset(&K, 0, sizeof K);
    K.width = K.height = 32, K.fx = K.fy = 16 / tan(M_PI / 6), K.cx = K.cy = 16;
    sooc_model_field *fld;
    CHECK_OK(sooc_model_field_create(&fld, sooc_mapper_model(mp), sooc_mapper_cogmap(mp), T, &K, 16, NULL));
    const sooc_field *f = sooc_model_field_get(fld);
    printf("field: %d components (layout + %d objects)\n", f->n_comp, f->n_comp - 1);
    CHECK(f->n_comp >= 2);
    CHECK(f->prepare(f->user, 2, 64) == SOOC_OK);
    /* eval: inside vs outside the first object's box */
    if (f->n_comp >= 2) {
        const sooc_render_box *b = &f->boxes[1];
        float pin[3] = {(float)b->T_fb[3], (float)(b->T_fb[7] + 0.3), (float)b->T_fb[11]};
        float pout[3] = {pin[0] + 2.0f, pin[1], pin[2]};
        float pts[6] = {pin[0], pin[1], pin[2], pout[0], pout[1], pout[2]}, sh[2], rgb[6];
        f->eval(f->user, 1, 1, pts, 2, sh, rgb);
        CHECK(sh[0] > 0 && sh[0] <= 1 && sh[1] == 0.0f);
        for (int i = 0; i < 6; i++) CHECK(rgb[i] >= 0 && rgb[i] <= 1);
        f->eval(f->user, 0, 0, pts, 2, sh, rgb);
        CHECK(sh[0] > 0 && sh[1] > 0);
    }
    sooc_model_field_destroy(fld);
    sooc_mapper_destroy(mp);
    remove(path);
    sooc_model_destroy(m);
    return check_report("test_model_mapper");
}
