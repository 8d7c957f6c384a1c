/* Keyframe bench: median and p99 of one online update (query ->
 * pad -> L refinement iterations -> register) at 64x64, K = 7, L = 3, 2
 * threads, through the public mapper API, and its ratio to the same update in
 * the PyTorch reference (bench/bench_keyframe_torch.py). JSON on the last line.
 *   bench_keyframe [--model M] [--slots K] [--rays G] [--rounds R] [--n N] [--tn TN] [--threads T] [--no-torch] [--dump F]
 *
 * The ratio is measured in interleaved rounds so that it is robust to the
 * load of other jobs on a shared machine: the PyTorch reference runs as one
 * persistent subprocess (--serve) that runs a batch of TN updates (at T and at
 * 1 thread, the faster median counts) each time it reads a line; each round is
 * one C batch of N updates followed by one PyTorch batch, and gives the ratio
 * of the two medians. The JSON reports every round's ratio, their median
 * (speedup_vs_torch) and minimum. median_ms / p99_ms are over all C updates.
 * Without --model a freshly initialised default-config model is used (the
 * cost does not depend on the weights). The camera path repeats every 64
 * frames so that every round sees the same kind of views. --dump F writes
 * the final map entries as text (%.17g, one entry a line) to F, to compare
 * results across builds and thread counts (identical files = bitwise equal).
 * --slots K runs the mapper with K object slots (sooc_mapper_params.slots),
 * the PyTorch reference with the same K. --rays G samples a G x G ray grid per
 * view (the default model's config; with --model, the model's own grid, e.g.
 * a `sooc3d model --rays 64` copy); the PyTorch reference runs the same grid. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>

#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "../tests/model/synth.h"
#ifdef MDL_PROFILE
#include "../src/model/step.h"
#endif

static int cmpd(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n) {
    qsort(v, n, sizeof(double), cmpd);
    return n ? v[n / 2] : -1.0;
}

/* The map entries as text, one a line, every number exact (%.17g). */
static int dump_entries(const sooc_mapper *mp, const char *path) {
    size_t ne = 0;
    sooc_mapper_entries(mp, NULL, 0, &ne);
    sooc_map_entry *e = calloc(ne ? ne : 1, sizeof *e);
    FILE *f = fopen(path, "w");
    int bad = !e || !f || sooc_mapper_entries(mp, e, ne, &ne);
    for (size_t i = 0; !bad && i < ne; i++) {
        fprintf(f, "%llu %.17g %.17g %.17g %.17g %.17g %.17g %.17g", (unsigned long long)e[i].id, e[i].x, e[i].z,
                e[i].yaw, e[i].sigma_t, e[i].sigma_yaw, (double)e[i].presence, (double)e[i].presence_logit);
        for (int j = 0; j < e[i].latent_dim; j++) fprintf(f, " %.17g %.17g", (double)e[i].what_mu[j], (double)e[i].what_logvar[j]);
        fprintf(f, " %u\n", e[i].obs_count);
    }
    int dl = sooc_mapper_layout_dim(mp);
    float mu[SOOC_MAP_LATENT_MAX], lv[SOOC_MAP_LATENT_MAX];
    int32_t bi, bj;
    if (!bad && dl > 0 && dl <= SOOC_MAP_LATENT_MAX && !sooc_mapper_last_layout(mp, &bi, &bj, mu, lv)) {
        fprintf(f, "layout %d %d", (int)bi, (int)bj);
        for (int j = 0; j < dl; j++) fprintf(f, " %.17g %.17g", (double)mu[j], (double)lv[j]);
        fprintf(f, "\n");
    }
    if (f && fclose(f)) bad = 1;
    free(e);
    return bad;
}

/* The PyTorch reference as a persistent child: write "n\n", read one line. */
typedef struct torch_proc {
    pid_t pid;
    FILE *in, *out;
} torch_proc;

static int torch_start(torch_proc *t, int threads, int K, int rays) {
    int pin[2], pout[2];
    if (pipe(pin) || pipe(pout)) return -1;
    fflush(stdout);
    pid_t pid = fork();
    if (pid < 0) return -1;
    if (pid == 0) {
        dup2(pin[0], 0);
        dup2(pout[1], 1);
        close(pin[0]), close(pin[1]), close(pout[0]), close(pout[1]);
        char script[512], th[16], ks[16], rs[16];
        snprintf(script, sizeof script, "%s/bench/bench_keyframe_torch.py", SOOC_SOURCE_DIR);
        snprintf(th, sizeof th, "%d", threads);
        snprintf(ks, sizeof ks, "%d", K);
        snprintf(rs, sizeof rs, "%d", rays);
        execl("/usr/bin/python3", "python3", script, "--serve", "--threads", th, "--K", ks, "--rays", rs, (char *)NULL);
        _exit(127);
    }
    close(pin[0]);
    close(pout[1]);
    t->pid = pid;
    t->in = fdopen(pin[1], "w");
    t->out = fdopen(pout[0], "r");
    return t->in && t->out ? 0 : -1;
}

/* Reads lines until one starting with `tag`; echoes others. Returns 0 on success. */
static int torch_read(torch_proc *t, const char *tag, char *line, size_t cap) {
    while (fgets(line, (int)cap, t->out)) {
        if (!strncmp(line, tag, strlen(tag))) return 0;
        fputs(line, stdout);
    }
    return -1;
}

/* One batch: "times <nt> <n> t... <nt> <n> t..." -> best (smallest) median and its samples. */
static double torch_batch(torch_proc *t, int n, double *samples, int *ns, int *best_nt) {
    static char line[1 << 16];
    fprintf(t->in, "%d\n", n);
    fflush(t->in);
    if (torch_read(t, "times", line, sizeof line)) return -1;
    char *q = line + 5, *e;
    double best = -1;
    double tmp[4096];
    for (;;) {
        long nt = strtol(q, &e, 10);
        if (e == q) break;
        q = e;
        long k = strtol(q, &e, 10);
        if (e == q || k <= 0 || k > 4096) break;
        q = e;
        for (long i = 0; i < k; i++) tmp[i] = strtod(q, &q);
        double med_copy[4096];
        memcpy(med_copy, tmp, sizeof(double) * k);
        double md = median(med_copy, (int)k);
        if (best < 0 || md < best) {
            best = md;
            *best_nt = (int)nt;
            memcpy(samples, tmp, sizeof(double) * k);
            *ns = (int)k;
        }
    }
    return best;
}

int main(int argc, char **argv) {
    /* On a shared 2-core machine libgomp's default busy-wait after each
     * parallel region costs 5x when the other core is taken. The policy is
     * read when libgomp loads, so re-exec once with it set (an explicit
     * OMP_WAIT_POLICY in the environment is respected). */
    if (!getenv("OMP_WAIT_POLICY")) {
        setenv("OMP_WAIT_POLICY", "passive", 1);
        execv("/proc/self/exe", argv);
    }
    const char *model = NULL, *dump = NULL;
    int rounds = 9, n = 12, tn = 6, threads = 2, torch = 1, slots = 0, rays = 0;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(argv[i], "--slots") && i + 1 < argc) slots = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--rays") && i + 1 < argc) rays = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--rounds") && i + 1 < argc) rounds = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--n") && i + 1 < argc) n = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--tn") && i + 1 < argc) tn = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--threads") && i + 1 < argc) threads = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-torch")) torch = 0;
        else if (!strcmp(argv[i], "--dump") && i + 1 < argc) dump = argv[++i];
        else {
            fprintf(stderr, "usage: bench_keyframe [--model M] [--slots K] [--rays G] [--rounds R] [--n N] [--tn TN] [--threads T] "
                            "[--no-torch] [--dump F]\n");
            return 2;
        }
    }
    if (rounds < 1 || rounds > 200 || n < 1 || n > 1000 || tn < 1 || tn > 4096) {
        fprintf(stderr, "bench_keyframe: rounds 1..200, n 1..1000, tn 1..4096\n");
        return 2;
    }
    if (rays && model) {
        fprintf(stderr, "bench_keyframe: --rays sets the default model's grid; for --model M write a copy with "
                        "`sooc3d model M --rays G --out F`\n");
        return 2;
    }
    char tmp[256];
    if (!model) {
        sooc_model_config c;
        sooc_model_config_default(&c);
        if (rays) c.ray_w = c.ray_h = rays;
        sooc_model *m;
        if (sooc_model_create(&m, &c, 1)) return fprintf(stderr, "%s\n", sooc_errmsg()), 1;
        snprintf(tmp, sizeof tmp, "/tmp/bench_keyframe_model.%d.bin", (int)getpid());
        if (sooc_model_save(m, tmp, NULL, 0)) return fprintf(stderr, "%s\n", sooc_errmsg()), 1;
        sooc_model_destroy(m);
        model = tmp;
    }
    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.model_path = model;
    p.threads = threads;
    p.iterations = 3;
    p.slots = slots;
    sooc_mapper *mp;
    if (sooc_mapper_create(&mp, &p)) return fprintf(stderr, "%s\n", sooc_errmsg()), 1;
    if (model == tmp) remove(tmp);
    int K = sooc_model_get_config(sooc_mapper_model(mp))->K;
    rays = sooc_model_get_config(sooc_mapper_model(mp))->ray_w;
    torch_proc tp = {0};
    char line[1024];
    if (torch) {
        signal(SIGPIPE, SIG_IGN);
        if (torch_start(&tp, threads, K, rays) || torch_read(&tp, "ready", line, sizeof line)) {
            fprintf(stderr, "bench_keyframe: the PyTorch reference did not start\n");
            return 1;
        }
        fputs(line, stdout);
    }
    synth_sphere sp[6] = {{{0.3, 0.4, 3.0}, 0.4, {0.9f, 0.2f, 0.1f}}, {{-0.8, 0.3, 2.2}, 0.3, {0.1f, 0.3f, 0.9f}},
                          {{1.2, 0.35, 4.5}, 0.35, {0.2f, 0.8f, 0.2f}}, {{-1.5, 0.5, 5.0}, 0.5, {0.8f, 0.8f, 0.1f}},
                          {{0.0, 0.25, 1.8}, 0.25, {0.7f, 0.1f, 0.7f}}, {{2.0, 0.4, 3.2}, 0.4, {0.1f, 0.8f, 0.8f}}};
    int warm = 5, tot = n * rounds;
    double *ms = malloc(sizeof(double) * tot), *tms = malloc(sizeof(double) * (size_t)tn * rounds);
    double *cr = malloc(sizeof(double) * n), ratio[200], rsort[200], cmed_r[200], tmed_r[200];
    int tnt_r[200], nt_all = 0;
    long nret = 0, nreg = 0;
    int fi = 0;
#ifdef MDL_PROFILE
    double ptot = 0;
#endif
    for (int r = -1; r < rounds; r++) {   /* round -1: warm-up of the C side */
        int cnt = r < 0 ? warm : n;
#ifdef MDL_PROFILE
        if (r == 0) memset(mdl_prof, 0, sizeof mdl_prof);
#endif
        for (int i = 0; i < cnt; i++, fi++) {
            double T[16];
            int j = fi % 64;
            double a = 0.05 * j;
            synth_pose(T, 0.3 * sin(a), 1.5, -0.5 + 0.02 * j, 0.2 * sin(0.7 * a), -0.45);
            sooc_frame f;
            if (synth_frame(&f, 64, 64, 60, T, sp, 6)) return 1;
            f.index = fi;
            f.t_ns = (int64_t)fi * 100000000;
            sooc_update_stats st;
            double t0 = sooc_seconds();
            if (sooc_mapper_update(mp, &f, &st)) return fprintf(stderr, "update: %s\n", sooc_errmsg()), 1;
            double dt = 1e3 * (sooc_seconds() - t0);
            if (r >= 0) {
                ms[r * n + i] = cr[i] = dt;
                nret += st.n_retrieved, nreg += st.n_registered;
#ifdef MDL_PROFILE
                ptot += dt;
#endif
            }
            sooc_frame_free(&f);
        }
        if (r < 0) continue;
        cmed_r[r] = median(cr, n);
        ratio[r] = -1;
        if (torch) {
            int ns = 0;
            tmed_r[r] = torch_batch(&tp, tn, tms + nt_all, &ns, &tnt_r[r]);
            if (tmed_r[r] <= 0) {
                fprintf(stderr, "bench_keyframe: the PyTorch reference stopped\n");
                return 1;
            }
            nt_all += ns;
            ratio[r] = tmed_r[r] / cmed_r[r];
            printf("round %d: C median %.2f ms, torch median %.2f ms (%d thread(s)), ratio %.2f\n", r, cmed_r[r],
                   tmed_r[r], tnt_r[r], ratio[r]);
        } else {
            printf("round %d: C median %.2f ms\n", r, cmed_r[r]);
        }
    }
    if (torch) {
        fclose(tp.in);   /* EOF: the server prints its summary and exits */
        while (fgets(line, sizeof line, tp.out)) fputs(line, stdout);
        fclose(tp.out);
        waitpid(tp.pid, NULL, 0);
    }
    qsort(ms, tot, sizeof(double), cmpd);
    double med = ms[tot / 2], p99 = ms[(int)(0.99 * (tot - 1))];
    size_t ne = 0;
    sooc_mapper_entries(mp, NULL, 0, &ne);
    printf("keyframe update 64x64 K=%d L=3 threads=%d: median %.2f ms, p99 %.2f ms (mean retrieved %.1f, registered %.1f, map %zu)\n",
           K, threads, med, p99, (double)nret / tot, (double)nreg / tot, ne);
#ifdef MDL_PROFILE
    {
        static const char *nm[MDL_PR_N] = {"dec_prep", "dec_fwd", "dec_comp", "dec_bwd", "dec_red", "aux",
                                           "conv0", "conv1", "conv2", "conv3", "fc", "lstm_gemm", "lstm_act", "head"};
        double acc = 0;
        for (int i = 0; i < MDL_PR_N; i++) {
            acc += 1e3 * mdl_prof[i];
            printf("profile %-13s %7.3f ms/update (%4.1f%%)\n", nm[i], 1e3 * mdl_prof[i] / tot,
                   100 * 1e3 * mdl_prof[i] / ptot);
        }
        printf("profile %-13s %7.3f ms/update (%4.1f%%)\n", "rest", (ptot - acc) / tot, 100 * (ptot - acc) / ptot);
    }
#endif
    if (dump && dump_entries(mp, dump)) return fprintf(stderr, "bench_keyframe: cannot write %s\n", dump), 1;
    sooc_mapper_destroy(mp);
    double tmed = -1, rmed = -1, rmin = -1;
    if (torch) {
        tmed = median(tms, nt_all);
        memcpy(rsort, ratio, sizeof(double) * rounds);
        rmed = median(rsort, rounds);
        rmin = rsort[0];
    }
    printf("{\"bench\":\"keyframe\",\"omp_wait_policy\":\"%s\",\"width\":64,\"height\":64,\"K\":%d,\"rays\":%d,\"L\":3,"
           "\"threads\":%d,\"n\":%d,\"rounds\":%d,\"median_ms\":%.3f,\"p99_ms\":%.3f,\"torch_median_ms\":%.3f,\"speedup_vs_torch\":%.2f,"
           "\"ratio_min\":%.2f,\"ratio_rounds\":[",
           getenv("OMP_WAIT_POLICY"), K, rays, threads, tot, rounds, med, p99, tmed, rmed, rmin);
    for (int r = 0; torch && r < rounds; r++) printf("%s%.2f", r ? "," : "", ratio[r]);
    printf("]}\n");
    free(ms);
    free(tms);
    free(cr);
    return 0;
}
