/* sooc3d train: train a SOOC3D model on synthetic scenes. */
#include "cli.h"
#include "sooc3d/model.h"
#include "sooc3d/train.h"

#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static volatile int g_stop;
static void on_signal(int sig) {
    (void)sig;
    g_stop = 1;
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d train --config F --data DIR [DIR...] --out DIR [--val DIR...] [--resume]\n"
            "                    [--init M] [--steps N] [--threads N] [--max-seconds S]\n"
            "                    [--calib F] [--format NAME] [--depth-scale S] [--depth-shift N] ...\n\n"
            "Train SOOC3D (ELBO + query objective) on scenes written by `sooc3d gen` and/or recorded sequences\n"
            "(7-Scenes, label-fusion, TUM, ...: the frames `sooc3d eval` holds out are never trained on; inputs and\n"
            "queries at least view_min_cm apart or view_min_deg turned; the support plane is kept in OUT/world;\n"
            "recorded_frac sets their share of the draws; docs/training.md \"Training from recordings\").\n"
            "  --config F       training YAML (training keys + a `model:` mapping); see models/*/config.yaml\n"
            "  --data DIR...    scene folders (or folders of scene_* folders, or recorded sequences) to train on\n"
            "  --val DIR...     held-out scenes for periodic validation (best.bin keeps the best mIoU)\n"
            "  --out DIR        checkpoints (last.bin, best.bin), log.csv, val.csv, curves.png\n"
            "  --resume         continue from DIR/last.bin with the same data order and RNG\n"
            "  --init M         new run from checkpoint M's weights (fine-tuning, e.g. to another clip\n"
            "                   depth); network shapes must match the config, optimiser starts fresh;\n"
            "                   with --resume an existing DIR/last.bin wins\n"
            "  --steps N        override the config's total steps\n"
            "  --threads N      decoder threads (default: all cores)\n"
            "  --max-seconds S  checkpoint and stop after S seconds (for time-sliced runs)\n"
            "Ctrl-C checkpoints and stops; --resume continues exactly.\n"
            "Data-parallel on Open MPI: mpirun -np N sooc3d train ... (each rank takes `accum` scenes of\n"
            "every step; rank 0 writes DIR; docs/cluster.md).\n\n%s",
            sooc_cli_framepath_help);
}

/* Fault injection for the MPI tests (docs/cluster.md): SOOC_TRAIN_KILL=R:S
 * makes rank R kill itself (SIGKILL) after step S. */
static int g_kill_rank = -1;
static long long g_kill_step = -1;
static void kill_hook(void *user, int64_t step) {
    (void)user;
    if (sooc_dist_rank() == g_kill_rank && step >= g_kill_step) raise(SIGKILL);
}

/* A failure on one rank ends the whole job (no rank waits forever in a
 * collective): the message names the rank, then MPI_Abort. */
static int train_fail(sooc_status s) {
    if (sooc_dist_size() > 1) {
        fprintf(stderr, "sooc3d train: rank %d of %d (%s): error (%s): %s\n", sooc_dist_rank(), sooc_dist_size(),
                sooc_dist_host(), sooc_status_str(s), sooc_errmsg());
        fflush(stderr);
        sooc_dist_abort(1);
    }
    int rc = sooc_cli_fail("train", s);
    sooc_dist_finalize();
    return rc;
}

/* Validation: provided by the evaluation path (src/train/validate.c). */
sooc_status sooc_train_validate(void *user, sooc_model *m, const sooc_dataset *val, double *miou,
                                double *miou_input, double *l2);

int sooc_cmd_train(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) { usage(stdout); return 0; }
    const char *config = NULL, *out = NULL, *init = NULL;
    const char *data[256], *val[256];
    int n_data = 0, n_val = 0, resume = 0, threads = -1, fo;
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    long long steps = 0;
    double max_s = 0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        if (!strcmp(a, "--config") && i + 1 < argc) config = argv[++i];
        else if (!strcmp(a, "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(a, "--resume")) resume = 1;
        else if (!strcmp(a, "--init") && i + 1 < argc) init = argv[++i];
        else if (!strcmp(a, "--steps") && i + 1 < argc) {
            if (!sooc_cli_count_opt("train", a, argv[++i], &steps)) return 2;
        }
        else if (!strcmp(a, "--threads") && i + 1 < argc) {
            if (!sooc_cli_int_opt("train", a, argv[++i], 0, 256, &threads)) return 2;
        } else if (!strcmp(a, "--max-seconds") && i + 1 < argc) {
            if (!sooc_cli_double_opt("train", a, argv[++i], 0, 1e7, &max_s)) return 2;
        }
        else if ((fo = sooc_cli_framepath_opt("train", argc, argv, &i, &fpp)) != 0) {
            if (fo < 0) return 2;
        }
        else if (!strcmp(a, "--data") || !strcmp(a, "--val")) {
            int is_val = !strcmp(a, "--val");
            while (i + 1 < argc && argv[i + 1][0] != '-') {
                if (is_val ? n_val >= 256 : n_data >= 256) { fprintf(stderr, "too many folders\n"); return 2; }
                if (is_val) val[n_val++] = argv[++i];
                else data[n_data++] = argv[++i];
            }
        } else {
            fprintf(stderr, "sooc3d train: unknown or incomplete option '%s'\n\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!config || !out || n_data == 0) { usage(stderr); return 2; }
    if (!sooc_cli_framepath_check("train", &fpp)) return 2;
    sooc_status s = sooc_dist_init(&argc, &argv);
    if (s) return train_fail(s);
    int rank = sooc_dist_rank(), nranks = sooc_dist_size();
    if (rank > 0) sooc_log_set_level(SOOC_LOG_WARN);   /* rank 0 reports; the others only warn */
    const char *kill = getenv("SOOC_TRAIN_KILL");
    if (kill && sscanf(kill, "%d:%lld", &g_kill_rank, &g_kill_step) != 2) g_kill_rank = -1;
    sooc_train_config cfg;
    sooc_model_config mc;
    sooc_train_config_default(&cfg);
    sooc_model_config_default(&mc);
    s = sooc_train_config_load(config, &cfg, &mc);
    if (s) return train_fail(s);
    if (steps > 0) cfg.steps = steps;
    if (threads >= 0) cfg.threads = threads;
    if (max_s > 0) cfg.val_max_seconds = (float)max_s;
    sooc_dataset *train = NULL, *valset = NULL;
    if (rank == 0 && nranks > 1)
        fprintf(stderr, "%d MPI ranks x %d scene(s) each = %d scenes per step\n", nranks, cfg.accum,
                nranks * cfg.accum);
    if (rank == 0) fprintf(stderr, "loading %d training folder(s)...\n", n_data);
    fpp.width = mc.img_w, fpp.height = mc.img_h;
    /* the support-plane warning of recorded sequences compares the camera's height with the range
     * the weights were trained at: the --init model's; a new model has none yet */
    fpp.cam_height_min_m = 1e-3, fpp.cam_height_max_m = 1e3;
    if (init) {
        sooc_model *im = NULL;
        if ((s = sooc_model_load(&im, init, NULL, NULL))) return train_fail(sooc_adderr(s, "--init %s", init));
        sooc_model_cam_heights_m(sooc_model_get_config(im), &fpp.cam_height_min_m, &fpp.cam_height_max_m);
        sooc_model_destroy(im);
    }
    /* recorded sequences: the view rule of the config (view_min_cm / view_min_deg),
     * eval's held-out frames never sampled, support plane kept in OUT/world
     * (docs/training.md "Training from recordings") */
    char world_dir[4096];
    snprintf(world_dir, sizeof world_dir, "%s/world", out);
    sooc_dataset_rec_params rec;
    sooc_dataset_rec_params_default(&rec);
    rec.view_min_cm = cfg.view_min_cm;
    rec.view_min_deg = cfg.view_min_deg;
    rec.world_dir = world_dir;
    /* under MPI rank 0 loads first (it may write OUT/world), then the others read */
    int ready = 1;
    if (rank > 0 && (s = sooc_dist_bcast(&ready, sizeof ready, "dataset loaded on rank 0"))) return train_fail(s);
    s = sooc_dataset_open_rec(&train, data, n_data, &fpp, &rec);
    if (s) return train_fail(s);
    if (n_val && rank == 0) {   /* validation runs on rank 0 only */
        s = sooc_dataset_open_rec(&valset, val, n_val, &fpp, &rec);
        if (s) { sooc_dataset_destroy(train); return train_fail(s); }
    }
    if (rank == 0 && (s = sooc_dist_bcast(&ready, sizeof ready, "dataset loaded on rank 0"))) return train_fail(s);
    sooc_dataset_set_unit(train, mc.unit_m);   /* query choice in model units (docs/model.md "Model unit") */
    if (valset) sooc_dataset_set_unit(valset, mc.unit_m);
    /* the camera heights this run trains at, stored in the model for the
     * frame path's and the node's warning (config cam_h_min / cam_h_max) */
    double hlo, hhi;
    if (sooc_dataset_cam_heights(train, &hlo, &hhi) > 0 && hlo > 0 && hhi > hlo) {
        mc.cam_h_min = (float)(hlo / mc.unit_m), mc.cam_h_max = (float)(hhi / mc.unit_m);
        if (rank == 0) fprintf(stderr, "training cameras %.2f-%.2f m above the support plane\n", hlo, hhi);
    }
    if (rank == 0)
        fprintf(stderr, "%d training scenes (%d recorded), %d validation scenes; %lld steps -> %s\n",
            sooc_dataset_n_scenes(train), sooc_dataset_n_recorded(train), valset ? sooc_dataset_n_scenes(valset) : 0,
            (long long)cfg.steps, out);
    signal(SIGINT, on_signal);
    signal(SIGTERM, on_signal);
    sooc_train_run_params rp = {config, out, resume, train, valset,
                                valset ? sooc_train_validate : NULL, &cfg, rank == 0, &g_stop, init,
                                g_kill_rank >= 0 ? kill_hook : NULL, NULL};
    s = sooc_train_run(&cfg, &mc, &rp);
    sooc_dataset_destroy(train);
    sooc_dataset_destroy(valset);
    if (s) return train_fail(s);
    sooc_dist_finalize();
    return 0;
}
