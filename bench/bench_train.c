/* Training-step bench: the wall time of one optimisation
 * step of the shipped unity configuration, through the real trainer
 * (sooc_train_run), after warm-up. JSON on the last line.
 *
 *   bench_train [--config F] [--model M] [--data DIR] [--scenes N] [--steps N]
 *               [--warmup N] [--threads T] [--accum A] [--seed S] [--keep]
 *   mpirun -np N bench_train ...   (data-parallel: docs/cluster.md; rank 0 prints)
 *
 * The model sizes are those of --model (default models/sooc3d_unity/model.bin,
 * trained with models/sooc3d_unity/config_col02.yaml); the training keys
 * (schedule, curriculum, accum, threads) come from --config (default that
 * config_col02.yaml), and the run starts from the model's weights (`--init`),
 * so the step costs what fine-tuning the shipped model costs. Scenes: --data
 * DIR (folders of scene_* folders), else N unity medium scenes generated into
 * a temporary folder (seed S, default 4242; not timed).
 *
 * Per step the trainer's log.csv gives sec_per_step (data sampling, the
 * model step over accum scenes, clipping and Adam; not logging or
 * checkpoints) and, where the trainer has them, the per-stage columns
 * (t_data, t_forward, t_backward, t_optim, t_allreduce, t_val). The first
 * --warmup steps are dropped; the JSON gives median, p10 and p90 of the rest
 * and the median of every stage column found. The machine may be shared:
 * the JSON also gives the process CPU seconds per step (all steps, warm-up
 * included) and the load average before and after, to read the wall times
 * against. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "sooc3d/model.h"
#include "sooc3d/gen.h"
#include "sooc3d/train.h"

#ifndef SOOC_SOURCE_DIR
#define SOOC_SOURCE_DIR "."
#endif

#define MAXROWS 100000
#define MAXC 40

static int cmpd(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

/* Quantile q of v[0..n) (sorted in place; nearest rank). */
static double quantile(double *v, int n, double q) {
    if (n <= 0) return NAN;
    qsort(v, (size_t)n, sizeof(double), cmpd);
    int i = (int)floor(q * (n - 1) + 0.5);
    return v[i < 0 ? 0 : i >= n ? n - 1 : i];
}

static double cpu_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double loadavg1(void) {
    double a = NAN;
    FILE *f = fopen("/proc/loadavg", "r");
    if (f) {
        if (fscanf(f, "%lf", &a) != 1) a = NAN;
        fclose(f);
    }
    return a;
}

static void git_commit(char *out, size_t cap) {
    snprintf(out, cap, "unknown");
    char cmd[1200];
    snprintf(cmd, sizeof cmd, "git -C '%s' rev-parse --short HEAD 2>/dev/null", SOOC_SOURCE_DIR);
    FILE *p = popen(cmd, "r");
    if (!p) return;
    if (fgets(out, (int)cap, p)) out[strcspn(out, "\n")] = 0;
    else snprintf(out, cap, "unknown");
    pclose(p);
}

static void die(const char *what, sooc_status s) {
    fprintf(stderr, "bench_train: %s: %s (%s)\n", what, sooc_errmsg(), sooc_status_str(s));
    exit(1);
}

int main(int argc, char **argv) {
    const char *config = SOOC_SOURCE_DIR "/models/sooc3d_unity/config_col02.yaml";
    const char *model = SOOC_SOURCE_DIR "/models/sooc3d_unity/model.bin";
    const char *data = NULL;
    int scenes = 4, steps = 40, warmup = 5, threads = -1, accum = 0, keep = 0;
    unsigned long long seed = 4242;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--config") && i + 1 < argc) config = argv[++i];
        else if (!strcmp(a, "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(a, "--data") && i + 1 < argc) data = argv[++i];
        else if (!strcmp(a, "--scenes") && i + 1 < argc) scenes = atoi(argv[++i]);
        else if (!strcmp(a, "--steps") && i + 1 < argc) steps = atoi(argv[++i]);
        else if (!strcmp(a, "--warmup") && i + 1 < argc) warmup = atoi(argv[++i]);
        else if (!strcmp(a, "--threads") && i + 1 < argc) threads = atoi(argv[++i]);
        else if (!strcmp(a, "--accum") && i + 1 < argc) accum = atoi(argv[++i]);
        else if (!strcmp(a, "--seed") && i + 1 < argc) seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(a, "--keep")) keep = 1;
        else {
            fprintf(stderr, "usage: bench_train [--config F] [--model M] [--data DIR] [--scenes N] [--steps N]\n"
                            "                   [--warmup N] [--threads T] [--accum A] [--seed S] [--keep]\n");
            return 2;
        }
    }
    if (scenes < 1 || steps < 1 || warmup < 0) {
        fprintf(stderr, "bench_train: --scenes and --steps must be >= 1, --warmup >= 0\n");
        return 2;
    }
    sooc_status s = sooc_dist_init(&argc, &argv);
    if (s) die("MPI", s);
    int rank = sooc_dist_rank();
    sooc_train_config cfg;
    sooc_model_config mc;
    sooc_train_config_default(&cfg);
    sooc_model_config_default(&mc);
    s = sooc_train_config_load(config, &cfg, &mc);
    if (s) die(config, s);
    sooc_model *m = NULL;
    if ((s = sooc_model_load(&m, model, NULL, NULL))) die(model, s);
    mc = *sooc_model_get_config(m);   /* the shipped model's sizes */
    size_t n_params = sooc_model_param_count(m);
    sooc_model_destroy(m);

    char tmp[] = "/tmp/sooc_bench_train_XXXXXX";
    if (!mkdtemp(tmp)) {
        perror("mkdtemp");
        return 1;
    }
    char gen_dir[600], out_dir[600];
    snprintf(gen_dir, sizeof gen_dir, "%s/data", tmp);
    snprintf(out_dir, sizeof out_dir, "%s/run", tmp);
    if (!data) {
        sooc_gen_params gp;
        sooc_gen_params_default(&gp);
        gp.preset = SOOC_GEN_UNITY;
        gp.scale = SOOC_GEN_M;
        gp.seed = seed;
        gp.n_scenes = scenes;
        gp.width = mc.img_w;
        gp.height = mc.img_h;
        gp.write_meshes = 0;
        gp.contact_sheet = 0;
        if (rank == 0) fprintf(stderr, "bench_train: generating %d unity m scenes in %s\n", scenes, gen_dir);
        if ((s = sooc_gen_run(&gp, gen_dir, NULL, NULL, NULL))) die("gen", s);
        data = gen_dir;
    }
    sooc_dataset *ds = NULL;
    const char *dirs[1] = {data};
    if ((s = sooc_dataset_open(&ds, dirs, 1, mc.img_w, mc.img_h))) die(data, s);
    sooc_dataset_set_unit(ds, mc.unit_m);

    cfg.steps = warmup + steps;
    cfg.log_every = 1;
    cfg.ckpt_every = cfg.steps;   /* one checkpoint, after the last step (outside the timed step) */
    cfg.val_every = 0;
    cfg.val_max_seconds = 0;
    if (threads >= 0) cfg.threads = threads;
    if (accum > 0) cfg.accum = accum;
    sooc_train_run_params rp;
    memset(&rp, 0, sizeof rp);
    rp.out_dir = out_dir;
    rp.train = ds;
    rp.init_path = model;
    double la0 = loadavg1(), c0 = cpu_seconds(), w0 = sooc_seconds();
    s = sooc_train_run(&cfg, &mc, &rp);
    double cpu = cpu_seconds() - c0, wall = sooc_seconds() - w0, la1 = loadavg1();
    if (s) die("train", s);
    sooc_dataset_destroy(ds);
    /* every rank's CPU seconds per step (rank 0 reports their sum) */
    double cpu_all = cpu / cfg.steps;
    if ((s = sooc_dist_sum_f64(&cpu_all, 1, "cpu seconds"))) die("MPI", s);
    /* the allreduce alone: 20 sums of a slab of the model's size, back to back
     * (each call waits for the slowest rank, so this is transfer + sync, not
     * the straggler wait that t_allreduce also holds) */
    double ar_med = NAN;
    if (sooc_dist_size() > 1) {
        float *slab = calloc(n_params, sizeof(float));
        double ar[20];
        if (!slab) die("allreduce slab", SOOC_ENOMEM);
        for (int i = 0; i < 23; i++) {
            double t0 = sooc_seconds();
            if ((s = sooc_dist_sum_f32(slab, n_params, "allreduce bench"))) die("MPI", s);
            if (i >= 3) ar[i - 3] = sooc_seconds() - t0;
        }
        free(slab);
        ar_med = quantile(ar, 20, 0.5);
    }
    if (rank > 0) {   /* rank 0 alone wrote the log */
        char cmd[700];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
        if (system(cmd) != 0) fprintf(stderr, "bench_train: could not remove %s\n", tmp);
        sooc_dist_finalize();
        return 0;
    }

    /* read the per-step rows back from log.csv */
    char log_path[700];
    snprintf(log_path, sizeof log_path, "%s/log.csv", out_dir);
    char *buf = NULL;
    size_t nb = 0;
    if ((s = sooc_file_read_all(log_path, (size_t)1 << 28, (void **)&buf, &nb))) die(log_path, s);
    char *names[MAXC];
    int nc = 0;
    char *save = NULL, *line = strtok_r(buf, "\n", &save);
    for (char *c = line; c && nc < MAXC;) {
        char *comma = strchr(c, ',');
        if (comma) *comma = 0;
        names[nc++] = c;
        c = comma ? comma + 1 : NULL;
    }
    static double col[MAXC][MAXROWS];
    int nr = 0;
    while ((line = strtok_r(NULL, "\n", &save)) && nr < MAXROWS) {
        char *c = line;
        double v[MAXC] = {0};
        for (int i = 0; i < nc; i++) {
            char *end;
            v[i] = strtod(c, &end);
            if (end == c) v[i] = NAN;
            char *comma = strchr(c, ',');
            if (!comma) {
                for (int j = i + 1; j < nc; j++) v[j] = NAN;
                break;
            }
            c = comma + 1;
        }
        if (v[0] < warmup) continue;   /* column 0 is the step */
        for (int i = 0; i < nc; i++) col[i][nr] = v[i];
        nr++;
    }
    int isec = -1;
    for (int i = 0; i < nc; i++)
        if (!strcmp(names[i], "sec_per_step")) isec = i;
    if (isec < 0 || nr == 0) {
        fprintf(stderr, "bench_train: %s has no sec_per_step rows after warm-up\n", log_path);
        return 1;
    }
    double med = quantile(col[isec], nr, 0.5), p10 = quantile(col[isec], nr, 0.1),
           p90 = quantile(col[isec], nr, 0.9);
    char stages[1024] = "";
    size_t sl = 0;
    for (int i = 0; i < nc; i++) {
        if (strncmp(names[i], "t_", 2) != 0) continue;
        double sm = quantile(col[i], nr, 0.5), mean = 0;
        for (int r = 0; r < nr; r++) mean += col[i][r] / nr;
        fprintf(stderr, "  %-12s median %.4f s  mean %.4f s\n", names[i], sm, mean);
        sl += (size_t)snprintf(stages + sl, sizeof stages - sl, "%s\"%s_median_s\": %.5f, \"%s_mean_s\": %.5f",
                               sl ? ", " : "", names[i], sm, names[i], mean);
        if (sl >= sizeof stages) break;
    }
    sooc_free(buf);
    char commit[64], ar_txt[32] = "null";   /* JSON has no NaN */
    git_commit(commit, sizeof commit);
    if (isfinite(ar_med)) snprintf(ar_txt, sizeof ar_txt, "%.5f", ar_med);
    fprintf(stderr, "bench_train: %d timed steps (after %d warm-up) on %d rank(s): median %.4f s, p10 %.4f, "
                    "p90 %.4f; %.3f cpu-s/step (all ranks); load %.2f -> %.2f\n",
            nr, warmup, sooc_dist_size(), med, p10, p90, cpu_all, la0, la1);
    if (!keep) {
        char cmd[700];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
        if (system(cmd) != 0) fprintf(stderr, "bench_train: could not remove %s\n", tmp);
    } else {
        fprintf(stderr, "bench_train: kept %s\n", tmp);
    }
    printf("{\"bench\": \"train\", \"commit\": \"%s\", \"config\": \"%s\", \"K\": %d, \"L\": %d, \"ray_grid\": %d, "
           "\"params\": %zu, \"ranks\": %d, \"accum\": %d, \"threads\": %d, \"steps\": %d, \"warmup\": %d, "
           "\"step_median_s\": %.5f, \"step_p10_s\": %.5f, \"step_p90_s\": %.5f, \"steps_per_s\": %.3f, "
           "\"cpu_s_per_step\": %.5f, \"allreduce_slab_median_s\": %s, \"wall_s\": %.2f, \"load_before\": %.2f, "
           "\"load_after\": %.2f%s%s}\n",
           commit, config, mc.K, mc.L, mc.ray_w, n_params, sooc_dist_size(), cfg.accum, cfg.threads, nr, warmup, med,
           p10, p90, 1.0 / med, cpu_all, ar_txt, wall, la0, la1, stages[0] ? ", " : "", stages);
    sooc_dist_finalize();
    return 0;
}
