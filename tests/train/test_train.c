/* Trainer: config loading (good and bad files), dataset loading and
 * sampling, and EXACT resume: 6 steps in one run give bit-identical
 * parameters to 3 steps + checkpoint + resume for 3 more. */
#include "check.h"
#include "sooc3d/gen.h"
#include "sooc3d/train.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static char g_dir[256];

static void write_text(const char *name, const char *text, char *path_out) {
    snprintf(path_out, 512, "%s/%s", g_dir, name);
    FILE *f = fopen(path_out, "w");
    fputs(text, f);
    fclose(f);
}

static void test_config(void) {
    char path[512];
    sooc_train_config c;
    sooc_model_config mc;
    sooc_train_config_default(&c);
    sooc_model_config_default(&mc);
    write_text("good.yaml", "steps: 42\nlr: 1.0e-3\ntau_end: 0.7\nmodel:\n  K: 3\n  d_what: 8\n  ref_ch: [8, 8, 16, 16]\n  slots: 5\n", path);
    CHECK_OK(sooc_train_config_load(path, &c, &mc));
    CHECK(c.steps == 42 && mc.K == 3 && mc.d_what == 8 && mc.ref_ch[3] == 16 && mc.slots == 5);
    CHECK_CLOSE(c.lr, 1e-3, 1e-9, 0);
    static const struct { const char *text, *needle; } bad[] = {
        {"steps: 10\nbogus: 1\n", "unknown key 'bogus'"},
        {"steps: 10\nlr: 1e-3\nsteps: 20\n", "duplicate key (first given at line 1)"},
        {"model:\n  K: 5\n  K: 6\n", "duplicate key"},
        {"steps: ten\n", "steps"},
        {"lr: 5\n", "outside"},
        {"steps: 1.5\n", "integer"},
        {"model:\n  K: 99\n", "K"},
        {"model:\n  slots: 99\n", "slots"},
        {"model:\n  K: 7\n  slots: 5\n", "slots = 5"},
        {"model: 3\n", "model"},
        {"model:\n  ref_ch: [1, 2]\n", "ref_ch"},
        {"steps: [\n", "YAML"},
        {"phase_a: 0.6\nphase_b: 0.5\n", "phase_b"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        sooc_train_config_default(&c);
        sooc_model_config_default(&mc);
        write_text("bad.yaml", bad[i].text, path);
        sooc_status s = sooc_train_config_load(path, &c, &mc);
        CHECK_MSG(s != SOOC_OK && strstr(sooc_errmsg(), bad[i].needle) && strstr(sooc_errmsg(), "bad.yaml"),
                  "case %zu: '%s'", i, sooc_errmsg());
    }
}

static void tiny_config(sooc_train_config *c, sooc_model_config *mc) {
    sooc_train_config_default(c);
    sooc_model_config_default(mc);
    mc->K = 3;
    mc->d_what = 8;
    mc->d_layout = 4;
    mc->L = 1;
    mc->dec_width = 16;
    mc->dec_color_width = 8;
    mc->ref_ch[0] = mc->ref_ch[1] = 8;
    mc->ref_ch[2] = mc->ref_ch[3] = 8;
    mc->ref_fc = 16;
    mc->ref_hidden = 16;
    c->steps = 6;
    c->warmup = 2;
    c->kl_warmup = 2;
    c->phase_a = 0.3f;
    c->phase_b = 0.6f;
    c->t_max_b = 2;
    c->t_max_c = 3;
    c->log_every = 1;
    c->ckpt_every = 100;
    c->val_every = 0;
    c->threads = 1;
}

static int read_params(const char *path, float **p, size_t *n) {
    sooc_model *m = NULL;
    if (sooc_model_load(&m, path, NULL, NULL)) return -1;
    *n = sooc_model_param_count(m);
    *p = malloc(*n * sizeof(float));
    memcpy(*p, sooc_model_params(m), *n * sizeof(float));
    sooc_model_destroy(m);
    return 0;
}

static void test_resume(void) {
    char data[512], outa[512], outb[512];
    snprintf(data, sizeof data, "%s/data", g_dir);
    snprintf(outa, sizeof outa, "%s/run_a", g_dir);
    snprintf(outb, sizeof outb, "%s/run_b", g_dir);
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.n_scenes = 3;
    gp.seed = 5;
    gp.density = 0.5;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    CHECK_OK(sooc_gen_run(&gp, data, NULL, NULL, NULL));
    sooc_dataset *ds = NULL;
    const char *dirs[1] = {data};
    CHECK_OK(sooc_dataset_open(&ds, dirs, 1, 64, 64));
    if (!ds) return;
    CHECK(sooc_dataset_n_scenes(ds) == 3);
    /* another size goes through the frame path (include/sooc3d/frame.h):
     * cropped/resized, depth kept valid */
    sooc_dataset *small = NULL;
    CHECK_OK(sooc_dataset_open(&small, dirs, 1, 32, 32));
    if (small) {
        const sooc_frame *f = sooc_dataset_view(small, 0, 0), *g = sooc_dataset_view(ds, 0, 0);
        size_t nv = 0, ng = 0;
        for (int i = 0; i < 32 * 32; i++) nv += f->valid[i] != 0;
        for (int i = 0; i < 64 * 64; i++) ng += g->valid[i] != 0;
        CHECK(f->width == 32 && f->height == 32 && f->K.width == 32 && fabs(f->K.fx - 0.5 * g->K.fx) < 1e-9);
        CHECK_MSG((double)nv / 1024.0 > 0.9 * (double)ng / 4096.0, "valid %zu / 1024 resized, %zu / 4096", nv, ng);
        CHECK(sooc_dataset_n_inputs(small, 0) == sooc_dataset_n_inputs(ds, 0));
    }
    sooc_dataset_destroy(small);
    /* sampling: T consecutive input views, Q query views, deterministic */
    sooc_frame v1[4], q1[2], v2[4], q2[2];
    int nv1, nq1, nv2, nq2;
    sooc_rng r1, r2;
    sooc_rng_seed(&r1, 3, 7);
    sooc_rng_seed(&r2, 3, 7);
    sooc_dataset_sample(ds, 1, 3, 2, 0, &r1, v1, &nv1, q1, &nq1);
    sooc_dataset_sample(ds, 1, 3, 2, 0, &r2, v2, &nv2, q2, &nq2);
    CHECK(nv1 == 3 && nq1 == 2 && nv1 == nv2 && nq1 == nq2);
    for (int i = 0; i < nv1; i++) CHECK(!v1[i].is_query && v1[i].index == v2[i].index);
    for (int i = 1; i < nv1; i++) CHECK(v1[i].index > v1[i - 1].index);
    for (int i = 0; i < nq1; i++) CHECK(q1[i].is_query && q1[i].index == q2[i].index);
    CHECK(nq1 < 2 || q1[0].index != q1[1].index);
    /* mode 1 (held-out views): outside the segment, distinct, deterministic,
     * and their object pixels are (>= 90%) objects the segment saw */
    for (int rep = 0; rep < 20; rep++) {
        sooc_rng_seed(&r1, 5, (uint64_t)rep);
        sooc_rng_seed(&r2, 5, (uint64_t)rep);
        sooc_dataset_sample(ds, rep % 3, 2, 2, 1, &r1, v1, &nv1, q1, &nq1);
        sooc_dataset_sample(ds, rep % 3, 2, 2, 1, &r2, v2, &nv2, q2, &nq2);
        CHECK(nq1 >= 1 && nq1 == nq2);
        for (int i = 0; i < nq1; i++) {
            CHECK(q1[i].index == q2[i].index);
            for (int t = 0; t < nv1; t++) CHECK(q1[i].index != v1[t].index);
            for (int j = 0; j < i; j++) CHECK(q1[i].index != q1[j].index);
            size_t np = (size_t)q1[i].width * (size_t)q1[i].height, obj = 0, cov = 0;
            for (size_t p = 0; p < np; p++) {
                uint16_t id = q1[i].instance[p];
                if (!id || !q1[i].valid[p]) continue;
                obj++;
                int seen = 0;
                for (int t = 0; t < nv1 && !seen; t++) {
                    size_t c = 0;
                    for (size_t p2 = 0; p2 < np; p2++) c += v1[t].instance[p2] == id && v1[t].valid[p2];
                    seen = c >= 16;
                }
                cov += (size_t)seen;
            }
            /* a fallback to mode 0 (no view qualified) returns query frames */
            CHECK(q1[i].is_query || (obj > 0 && cov >= 0.9 * obj));
        }
    }

    sooc_train_config c;
    sooc_model_config mc;
    tiny_config(&c, &mc);
    sooc_train_run_params rp = {NULL, outa, 0, ds, NULL, NULL, NULL, 0, NULL, NULL, NULL, NULL};
    CHECK_OK(sooc_train_run(&c, &mc, &rp));
    /* b: stop after 3 steps, then resume */
    sooc_train_config c3 = c;
    c3.steps = 6;
    volatile int stop = 0;
    rp.out_dir = outb;
    /* Run 3 steps by training with a total of 6 but a stop flag set from the
     * start: the loop checks it after each step. */
    stop = 1;
    rp.stop_flag = &stop;
    CHECK_OK(sooc_train_run(&c3, &mc, &rp));   /* 1 step, then stops */
    rp.resume = 1;
    CHECK_OK(sooc_train_run(&c3, &mc, &rp));   /* step 2 */
    CHECK_OK(sooc_train_run(&c3, &mc, &rp));   /* step 3 */
    stop = 0;
    CHECK_OK(sooc_train_run(&c3, &mc, &rp));   /* steps 4..6 */
    /* without --resume an existing run is refused */
    rp.resume = 0;
    CHECK(sooc_train_run(&c3, &mc, &rp) == SOOC_EINVAL && strstr(sooc_errmsg(), "--resume"));
    char pa[600], pb[600];
    snprintf(pa, sizeof pa, "%s/last.bin", outa);
    snprintf(pb, sizeof pb, "%s/last.bin", outb);
    float *wa = NULL, *wb = NULL;
    size_t na = 0, nb = 0;
    CHECK(read_params(pa, &wa, &na) == 0);
    CHECK(read_params(pb, &wb, &nb) == 0);
    CHECK(na == nb && na > 0);
    size_t diff = 0;
    for (size_t i = 0; i < na && i < nb; i++) diff += memcmp(&wa[i], &wb[i], sizeof(float)) != 0;
    CHECK_MSG(diff == 0, "%zu of %zu parameters differ after resume", diff, na);
    /* training moved the parameters away from the initial ones */
    sooc_model *m0 = NULL;
    CHECK_OK(sooc_model_create(&m0, &mc, c.init_seed));
    size_t moved = 0;
    for (size_t i = 0; m0 && i < na; i++) moved += sooc_model_params(m0)[i] != wa[i];
    CHECK_MSG(moved > na / 10, "only %zu of %zu parameters changed", moved, na);
    sooc_model_destroy(m0);
    /* --init (fine-tuning): run a's weights, another clip depth, one step; the
     * weights move by about one Adam step (<= lr each) from run a's, and the
     * new config's clip is the checkpoint's. A network-shape mismatch is an
     * error naming the file and the field, and writes no run; more slots than
     * the checkpoint's are added (widened). */
    {
        char outc[600], outd[600], pc[620];
        snprintf(outc, sizeof outc, "%s/run_c", g_dir);
        snprintf(outd, sizeof outd, "%s/run_d", g_dir);
        sooc_train_config c1 = c;
        sooc_model_config mc5 = mc;
        mc5.d_clip = 5.0f;
        volatile int stop1 = 1;
        sooc_train_run_params ri = {NULL, outc, 0, ds, NULL, NULL, NULL, 0, &stop1, pa, NULL, NULL};
        CHECK_OK(sooc_train_run(&c1, &mc5, &ri));
        snprintf(pc, sizeof pc, "%s/last.bin", outc);
        float *wc = NULL;
        size_t nc = 0;
        CHECK(read_params(pc, &wc, &nc) == 0);
        double dmax = 0;
        for (size_t i = 0; wc && i < nc && nc == na; i++) dmax = fmax(dmax, fabs((double)wc[i] - wa[i]));
        CHECK_MSG(nc == na && dmax > 0 && dmax <= 1.01 * c.lr, "max |w - w_init| %g after one step (lr %g)", dmax,
                  (double)c.lr);
        sooc_model *mm = NULL;
        CHECK_OK(sooc_model_load(&mm, pc, NULL, NULL));
        CHECK(mm && sooc_model_get_config(mm)->d_clip == 5.0f);
        sooc_model_destroy(mm);
        free(wc);
        sooc_model_config mk = mc;
        mk.d_what = mc.d_what + 1;
        ri.out_dir = outd;
        CHECK(sooc_train_run(&c1, &mk, &ri) == SOOC_EINVAL && strstr(sooc_errmsg(), "run_a/last.bin") &&
              strstr(sooc_errmsg(), "its d_what differs"));
        snprintf(pc, sizeof pc, "%s/last.bin", outd);
        CHECK(!sooc_file_exists(pc));
        /* more slots than the checkpoint: widened (sooc_model_copy_slots), then trained */
        mk = mc;
        mk.K = mc.K + 1;
        CHECK_OK(sooc_train_run(&c1, &mk, &ri));
        CHECK_OK(sooc_model_load(&mm, pc, NULL, NULL));
        CHECK(mm && sooc_model_get_config(mm)->K == mc.K + 1 &&
              sooc_model_param_count(mm) > na);
        if (mm) {
            const float *w = sooc_model_params(mm);
            double dm = 0;   /* every weight ahead of the slot priors started at run a's */
            sooc_model_tensor t[64];
            int nt = sooc_model_tensors(mm, t, 64);
            size_t prior_off = na;
            for (int i = 0; i < nt; i++)
                if (!strcmp(t[i].name, "prior.slots")) prior_off = t[i].offset;
            for (size_t i = 0; i < prior_off; i++) dm = fmax(dm, fabs((double)w[i] - wa[i]));
            CHECK_MSG(prior_off < na && dm > 0 && dm <= 1.01 * c.lr, "widened run: max |w - w_a| %g", dm);
        }
        sooc_model_destroy(mm);
        /* every pixel (64 x 64 rays) from the 32 x 32 checkpoint: the same weights
         * (sooc_mdl_ref_flatten pools), one step on the new grid */
        char oute[600];
        snprintf(oute, sizeof oute, "%s/run_e", g_dir);
        mk = mc;
        mk.ray_w = mk.ray_h = 64;
        ri.out_dir = oute;
        CHECK(mc.ray_w == 32 && mc.img_w == 64);
        CHECK_OK(sooc_train_run(&c1, &mk, &ri));
        snprintf(pc, sizeof pc, "%s/last.bin", oute);
        CHECK_OK(sooc_model_load(&mm, pc, NULL, NULL));
        CHECK(mm && sooc_model_get_config(mm)->ray_w == 64 && sooc_model_param_count(mm) == na);
        if (mm) {
            const float *w = sooc_model_params(mm);
            double dm = 0;
            for (size_t i = 0; i < na; i++) dm = fmax(dm, fabs((double)w[i] - wa[i]));
            CHECK_MSG(dm > 0 && dm <= 1.01 * c.lr, "64 x 64 ray run: max |w - w_a| %g", dm);
        }
        sooc_model_destroy(mm);
    }
    /* the logs hold one row per step, without duplicates after resume */
    char la[600], lb[600];
    snprintf(la, sizeof la, "%s/log.csv", outa);
    snprintf(lb, sizeof lb, "%s/log.csv", outb);
    void *ba = NULL, *bb = NULL;
    size_t sa = 0, sb = 0;
    CHECK_OK(sooc_file_read_all(la, 1 << 20, &ba, &sa));
    CHECK_OK(sooc_file_read_all(lb, 1 << 20, &bb, &sb));
    int rows_a = 0, rows_b = 0;
    for (size_t i = 0; i < sa; i++) rows_a += ((char *)ba)[i] == '\n';
    for (size_t i = 0; i < sb; i++) rows_b += ((char *)bb)[i] == '\n';
    CHECK_MSG(rows_a == 7 && rows_b == 7, "log rows %d and %d, expected 7 (header + 6)", rows_a, rows_b);
    sooc_free(ba);
    sooc_free(bb);
    free(wa);
    free(wb);
    sooc_dataset_destroy(ds);
}

int main(void) {
    snprintf(g_dir, sizeof g_dir, "/tmp/sooc_train_XXXXXX");
    if (!mkdtemp(g_dir)) return 1;
    test_config();
    test_resume();
    char cmd[300];
    snprintf(cmd, sizeof cmd, "rm -rf %s", g_dir);
    if (!g_check_fail && system(cmd) != 0) fprintf(stderr, "could not remove %s\n", g_dir);
    return check_report("test_train");
}
