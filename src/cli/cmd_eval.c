/* sooc3d eval: the paper's Table 1 (and the supplementary table) for one or
 * more models on `sooc3d gen` datasets, through the one evaluation path
 * (sooc_eval_run_scene), averaged over runs with different seeds. */
#include "cli.h"
#include "cmd_eval_real.h"
#include "sooc3d/eval.h"
#include "sooc3d/train.h"
#include "sooc3d/render.h"
#include "sooc3d/model.h"
#include "sooc3d/gen.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define MAX_MODELS 16
#define MAX_DIRS 64

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d eval --model M [--model M2 ...] [--name N ...] --data DIR [DIR...] --json OUT\n"
            "                   [--md OUT] [--runs R] [--seed S] [--input-timing final|online|both]\n"
            "                   [--scenes N] [--samples C,F] [--threads T] [--iterations L]\n"
            "                   [--max-views N] [--max-obj K] [--clip D] [--merge R] [--revisit] [--gate M,R,P]\n"
            "                   [--latents mean|sample] [--slots N] [--invalid-depth free|unknown] [--quiet]\n"
            "                   recorded sequences: [--query-every N] [--no-second-pass] [--seen-tol M]\n"
            "                   [--seen-height M] [--persist-min K] [--panels DIR]\n\n"
            "For every scene of every DIR (a `sooc3d gen` output: scene_* folders, or one scene folder;\n"
            "the scale s/m/l/xl comes from each scene.yaml) and every model: online inference over the\n"
            "input views with a fresh cognitive map, then every view is rendered with the dense renderer\n"
            "and scored (docs/metrics.md). Prints the paper's Table 1 (rows model x {I, Q};\n"
            "columns mIoU, RGB RMSE, depth RMSE, L2 per scale) and the supplementary table (Hungarian\n"
            "mIoU, matched fraction, recall by distance); writes them as JSON (--json) and Markdown (--md).\n\n"
            "  --model         model checkpoint; repeat for several models (rows of the table)\n"
            "  --name          row name of the i-th model (default: its folder name, or file stem)\n"
            "  --data          dataset directories (several may follow one --data)\n"
            "  --runs          R runs with seeds S, S+1, ...; cells give mean +- std over runs (1)\n"
            "  --seed          first posterior-sampling seed (1)\n"
            "  --input-timing  input views rendered from the final map (final, default), right after\n"
            "                  their own update (online, MulMON protocol), or both (extra rows\n"
            "                  '<name> online'); query views always from the final map\n"
            "  --scenes        at most N scenes per DIR (default all)\n"
            "  --samples       coarse,fine samples per ray (96,32)\n"
            "  --threads       model/renderer threads (0 = OpenMP default)\n"
            "  --iterations    refinement updates per input view (default: the model's L)\n"
            "  --baseline geometric  also a 'geometric' row: the support plane, then Euclidean clustering of\n"
            "                  the points above it over the mapped frames, each cluster an object\n"
            "                  (docs/geometric.md); scored on the same views as the models\n"
            "  --proposals     the mapper places the slots it pads with priors on each keyframe's\n"
            "                  support-plane clusters (docs/geometric.md \"Proposals\")\n"
            "  --geo-support M the mapper removes entries that stand on no support-plane cluster of\n"
            "                  the mapped keyframes (M: margin around a cluster's box, metres;\n"
            "                  docs/geometric.md \"Geometric support\")\n"
            "  --surface       the views scored from the final map are segmented by the entries'\n"
            "                  observed surfaces: the mapped frames' support-plane clusters, each\n"
            "                  object voxel claimed by the entry densest there (docs/geometric.md\n"
            "                  \"The entries' observed surfaces\"); the render is the model's\n"
            "  --surface-fill  with --surface: a claimed cluster's unclaimed voxels go to its largest\n"
            "                  claimant\n"
            "  --surface-share F   with --surface: a claimant with less than F of a cluster's claimed\n"
            "                  voxels gives them to its largest claimant (0)\n"
            "  --surface-sigma S   with --surface: the least density that claims a voxel (0.01)\n"
            "  --surface-boxes with --geo-support: the mapper gives its entries the boxes of the\n"
            "                  surfaces they claim (node key model.surface_boxes)\n"
            "  --finetune      SOOC3D+: also a '<name>+ft' row per model: online inference as for the\n"
            "                  base row, then per-object NeRF finetuning by EM on the input views\n"
            "                  (sooc3d finetune), then the same views scored from the finetuned map;\n"
            "                  on a recorded sequence: the mapped frames finetune, the held-out query\n"
            "                  frames score (a '<name>+ft' cell, no second pass)\n"
            "  --ft-iterations, --ft-rays, --ft-lr, --ft-lr-final   finetuning steps per object /\n"
            "                  block, rays per step, Adam learning rate, its final fraction after a\n"
            "                  half-cosine decay (defaults: those of sooc3d finetune)\n"
            "  --ft-support M  finetuning: surfaces within M metres of the support plane are the\n"
            "                  layout's, objects are kept empty there (0 = off, default;\n"
            "                  docs/finetune.md \"The support plane\")\n"
            "  --ft-no-birth   no births and deaths: by default, before finetuning, new entries go\n"
            "                  where the input views show a surface the map does not draw, and after\n"
            "                  it the entries whose density is empty are removed (docs/finetune.md\n"
            "                  \"Births and deaths\")\n"
            "  --ft-birth-margin U   births: how far behind the sensor's surface the rendered one\n"
            "                  must lie, model units (default 0.15)\n"
            "  --mesh-res N    mesh accuracy / completeness (JSON mesh_acc_cm, mesh_comp_cm; Atlas,\n"
            "                  docs/mesh.md): marching cubes with N samples per object box axis\n"
            "                  (default 64); 0 = no mesh metrics\n"
            "  --max-views     map only the first N input views of a scene (and score the query\n"
            "                  views near them); 0 = all (default)\n"
            "  --max-obj       render at most K in-view objects per view (default: all, up to 63)\n"
            "  --clip          clip depth in metres for inference and scoring (default: the model's\n"
            "                  d_clip): pixels beyond it are masked, objects beyond it are out of view\n"
            "  --merge         SOOC3D mapper: duplicate radius R m (entries one view registers closer\n"
            "                  than R are merged; a new entry that close to an older one is dropped)\n"
            "                  0 = never (default: the paper registers without object matching);\n"
            "                  0.35 measured best (docs/cogmap.md \"Merging split objects\")\n"
            "  --revisit       SOOC3D mapper, with --merge: the node's revisit rules (merge with\n"
            "                  unregistered neighbours, hold entries that left the view, running-mean\n"
            "                  updates, retire entries the depth keeps showing as free space;\n"
            "                  docs/cogmap.md \"Revisits\")\n"
            "  --gate          with --revisit: the creation gate of new entries (launch keys\n"
            "                  model.gate_min_rays, gate_ratio, gate_part; 0 = default, -1 = that test\n"
            "                  off; docs/cogmap.md \"Revisits\" rule 5)\n"
            "  --latents       SOOC3D mapper: refine on the posterior means (mean, default) or on one\n"
            "                  posterior sample per iteration as in training (sample); docs/model.md\n"
            "  --slots         SOOC3D mapper: object slots per view; 0 = the model's setting (default:\n"
            "                  its config slots, else K). More than K pads the extra slots with\n"
            "                  mirrored learnt priors (docs/model.md)\n"
            "  --invalid-depth pixels without valid depth: free (no surface up to d_clip) or unknown\n"
            "                  (sensor holes, masked out of the model's likelihood); default: the\n"
            "                  model's config.invalid_depth (docs/model.md \"Invalid depth\")\n"
            "  --quiet         no progress line\n\n%s\n%s",
            sooc_cli_framepath_help, sooc_eval_real_cli_help);
}

static void model_name(const char *path, char *out, size_t cap) {
    const char *b = strrchr(path, '/');
    b = b ? b + 1 : path;
    size_t n = strlen(b);
    const char *dot = strrchr(b, '.');
    if (!strcmp(b, "model.bin") || !strcmp(b, "best.bin") || !strcmp(b, "last.bin")) {
        /* models/<name>/model.bin -> <name> (best.bin / last.bin keep a suffix) */
        if (b > path + 1) {
            const char *e = b - 1, *s = e;
            while (s > path && s[-1] != '/') s--;
            if (!strcmp(b, "model.bin"))
                snprintf(out, cap, "%.*s", (int)(e - s), s);
            else
                snprintf(out, cap, "%.*s/%.*s", (int)(e - s), s, (int)(n - 4), b);
            if (*out) return;
        }
    }
    snprintf(out, cap, "%.*s", (int)(dot ? (size_t)(dot - b) : n), b);
}

typedef struct prog_ctx {
    sooc_progress pr;
    uint64_t done, total;
    int quiet;
    char extra[160];
    double t0;
} prog_ctx;

static sooc_status on_view(void *user, const sooc_eval_view_info *v) {
    (void)v;
    prog_ctx *p = user;
    p->done++;
    if (!p->quiet) sooc_progress_update(&p->pr, p->done < p->total ? p->done : p->total, p->extra);
    return SOOC_OK;
}

static void fmt_stat(char *b, size_t cap, const sooc_eval_stat *s, int runs) {
    if (!isfinite(s->mean)) snprintf(b, cap, "-");
    else if (runs > 1) snprintf(b, cap, "%.3f+-%.3f", s->mean, s->std);
    else snprintf(b, cap, "%.3f", s->mean);
}

/* The supplementary table (the library's text output holds Table 1 only). */
static void print_supp(const sooc_eval_table *t, char names[][160], int n_names, const int *scales_used, int runs) {
    printf("\nSupplementary: one-to-one (Hungarian) mIoU, fraction of visible GT objects matched, recall by\n"
           "camera distance (matched fraction of visible GT objects per distance bin), RGB RMSE over object\n"
           "pixels (GT instance != 0).\n");
    printf("%-16s %-2s %-5s %7s  %-14s %-14s %-14s %-14s %-14s %-16s\n", "model", "IQ", "scale", "views",
           "mIoU Hungarian", "matched", "recall <3 m", "recall 3-5 m", "recall >5 m", "RGB RMSE objects");
    for (int m = 0; m < n_names; m++)
        for (int q = 0; q < 2; q++)
            for (int s = 0; s < SOOC_N_SCALES; s++) {
                if (!scales_used[s]) continue;
                sooc_eval_cell c;
                if (sooc_eval_table_cell(t, names[m], s, q, &c)) {
                    sooc_clearerr();
                    continue;
                }
                char a[6][48];
                fmt_stat(a[0], sizeof a[0], &c.miou_hung, runs);
                fmt_stat(a[1], sizeof a[1], &c.matched_frac, runs);
                for (int k = 0; k < 3 && k < SOOC_METRIC_N_DBINS; k++) fmt_stat(a[2 + k], sizeof a[2 + k], &c.recall[k], runs);
                fmt_stat(a[5], sizeof a[5], &c.rgb_rmse_obj, runs);
                printf("%-16s %-2s %-5s %7ld  %-14s %-14s %-14s %-14s %-14s %-16s\n", names[m], q ? "Q" : "I",
                       sooc_scale_name(s), c.n_views, a[0], a[1], a[2], a[3], a[4], a[5]);
            }
}

/* Object geometry for planners (eval_geom.h, docs/metrics.md): per
 * query cell with a scene description (the geometry comes from the final map). */
static void print_geom(const sooc_eval_table *t, char names[][160], int n_names, const int *scales_used, int runs) {
    int any = 0;
    for (int m = 0; m < n_names; m++)
        for (int s = 0; s < SOOC_N_SCALES; s++) {
            sooc_eval_cell c;
            if (!scales_used[s] || sooc_eval_table_cell(t, names[m], s, 1, &c)) {
                sooc_clearerr();
                continue;
            }
            if (!isfinite(c.extent_err_cm.mean) && !isfinite(c.sigma1_frac.mean)) continue;
            if (!any++)
                printf("\nObject geometry (final map, GT objects matched to the nearest entry within 0.5 m): median\n"
                       "extent error of the tight boxes (cm), position error axes within one sigma, symmetry flag\n"
                       "agreeing with the GT shape.\n%-16s %-5s %-14s %-14s %-14s\n",
                       "model", "scale", "extent_err_cm", "sigma1_frac", "symmetric");
            char a[3][48];
            fmt_stat(a[0], sizeof a[0], &c.extent_err_cm, runs);
            fmt_stat(a[1], sizeof a[1], &c.sigma1_frac, runs);
            fmt_stat(a[2], sizeof a[2], &c.symmetric_agree, runs);
            printf("%-16s %-5s %-14s %-14s %-14s\n", names[m], sooc_scale_name(s), a[0], a[1], a[2]);
        }
}

int sooc_cmd_eval(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *models[MAX_MODELS], *names[MAX_MODELS], *dirs[MAX_DIRS];
    int n_models = 0, n_names = 0, n_dirs = 0;
    const char *json = NULL, *md = NULL;
    int runs = 1, max_scenes = -1, quiet = 0, timing = SOOC_EVAL_FINAL, finetune = 0;
    sooc_finetune_params ftp;
    sooc_finetune_params_default(&ftp);
    sooc_birth_params bp;
    sooc_birth_params_default(&bp);
    int no_birth = 0, geometric = 0;
    sooc_proposal_params prop;
    memset(&prop, 0, sizeof prop);
    uint64_t seed = 1;
    int mesh_res = SOOC_MESH_RES_DEFAULT;
    sooc_eval_run_opts ro;
    sooc_eval_run_opts_default(&ro);
    sooc_eval_real_opts rel;   /* recorded sequences (cmd_eval_real.c) */
    sooc_eval_real_opts_default(&rel);
    sooc_cluster_params surf_cp;
    const char *panels = NULL;
    sooc_framepath_params fpp;   /* the frame path (--calib, --depth-scale, --up, ...) */
    sooc_framepath_params_default(&fpp);
    int fo;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
#define INTV(lo, hi, x) do { if (!sooc_cli_int_opt("eval", a, argv[++i], lo, hi, x)) return 2; } while (0)
        if ((fo = sooc_cli_framepath_opt("eval", argc, argv, &i, &fpp)) != 0) {
            if (fo < 0) return 2;
        } else if (!strcmp(a, "--model") && has) {
            if (n_models == MAX_MODELS) { fprintf(stderr, "sooc3d eval: at most %d models\n", MAX_MODELS); return 2; }
            models[n_models++] = argv[++i];
        } else if (!strcmp(a, "--name") && has) {
            if (n_names == MAX_MODELS) { fprintf(stderr, "sooc3d eval: at most %d names\n", MAX_MODELS); return 2; }
            names[n_names++] = argv[++i];
        } else if (!strcmp(a, "--data") && has) {
            while (i + 1 < argc && strncmp(argv[i + 1], "--", 2)) {
                if (n_dirs == MAX_DIRS) { fprintf(stderr, "sooc3d eval: at most %d data dirs\n", MAX_DIRS); return 2; }
                dirs[n_dirs++] = argv[++i];
            }
        } else if (!strcmp(a, "--json") && has) {
            json = argv[++i];
            if (sooc_cli_need_parent("eval", a, json)) return 2;
        } else if (!strcmp(a, "--md") && has) {
            md = argv[++i];
            if (sooc_cli_need_parent("eval", a, md)) return 2;
        }
        else if (!strcmp(a, "--runs") && has) INTV(1, 1000, &runs);
        else if (!strcmp(a, "--seed") && has) { if (!sooc_cli_u64_opt("eval", a, argv[++i], UINT64_MAX, &seed)) return 2; }
        else if (!strcmp(a, "--input-timing") && has) {
            timing = sooc_eval_timing_parse(argv[++i]);
            if (timing < 0) { fprintf(stderr, "sooc3d eval: --input-timing must be final, online or both\n"); return 2; }
        } else if (!strcmp(a, "--scenes") && has) INTV(1, 1000000, &max_scenes);
        else if (!strcmp(a, "--samples") && has) {
            if (!sooc_cli_parse_samples(argv[++i], &ro.n_coarse, &ro.n_fine)) {
                fprintf(stderr, "sooc3d eval: --samples wants C[,F] with C >= 2, F >= 0\n");
                return 2;
            }
        } else if (!strcmp(a, "--threads") && has) INTV(0, 256, &ro.threads);
        else if (!strcmp(a, "--iterations") && has) INTV(0, 16, &ro.iterations);
        else if (!strcmp(a, "--finetune")) finetune = 1;
        else if (!strcmp(a, "--proposals")) {
            if (!prop.on) sooc_proposal_params_default(&prop), prop.on = 1;
            ro.proposals = &prop;
        } else if (!strcmp(a, "--prop-only")) {   /* only proposals make new entries */
            if (!prop.on) sooc_proposal_params_default(&prop), prop.on = 1;
            prop.rest_logit = -20, ro.proposals = &prop;
        } else if (!strcmp(a, "--prop-join") && has) {
            if (!prop.on) sooc_proposal_params_default(&prop), prop.on = 1;
            if (!sooc_cli_double_opt("eval", a, argv[++i], 1e-3, 1, &prop.cluster.dist_m)) return 2;
            ro.proposals = &prop;
        } else if (!strcmp(a, "--surface")) {
            sooc_cluster_params_default(&surf_cp), ro.surface = &surf_cp;
        } else if (!strcmp(a, "--surface-sigma") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0, 1, &ro.surface_p.min_sigma)) return 2;
        } else if (!strcmp(a, "--surface-share") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0, 1, &ro.surface_p.min_share)) return 2;
        } else if (!strcmp(a, "--surface-boxes")) {
            ro.surface_boxes = 1;
        } else if (!strcmp(a, "--surface-fill")) {
            ro.surface_p.fill = 1;
        } else if (!strcmp(a, "--geo-support") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], 1e-4, 1, &ro.geo_support_m)) return 2;
        } else if (!strcmp(a, "--prop-logit") && has) {
            if (!prop.on) sooc_proposal_params_default(&prop), prop.on = 1;
            if (!sooc_cli_double_opt("eval", a, argv[++i], -20, 20, &prop.pres_logit)) return 2;
            ro.proposals = &prop;
        }
        else if (!strcmp(a, "--baseline") && has) {
            if (strcmp(argv[++i], "geometric")) {
                fprintf(stderr, "sooc3d eval: unknown baseline '%s' (known: geometric)\n", argv[i]);
                return 2;
            }
            geometric = 1;
        }
        else if (!strcmp(a, "--ft-no-birth")) no_birth = 1;
        else if (!strcmp(a, "--ft-birth-margin") && has) {
            double d;
            if (!sooc_cli_double_opt("eval", a, argv[++i], 1e-3, 100, &d)) return 2;
            bp.depth_margin = (float)d;
        }
        else if (!strcmp(a, "--ft-iterations") && has) INTV(0, 1000000, &ftp.iterations);
        else if (!strcmp(a, "--ft-rays") && has) INTV(1, 1 << 20, &ftp.rays);
        else if (!strcmp(a, "--ft-support") && has) {
            double d;
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0, 1, &d)) return 2;
            ftp.support_m = (float)d;
        } else if (!strcmp(a, "--ft-lr-final") && has) {
            double d;
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0, 1, &d)) return 2;
            ftp.lr_final = (float)d;
        } else if (!strcmp(a, "--ft-lr") && has) {
            double d;
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0, 1, &d)) return 2;
            ftp.lr = ftp.lr_z = (float)d;
        }
        else if (!strcmp(a, "--mesh-res") && has) INTV(0, 1024, &mesh_res);
        else if (!strcmp(a, "--max-views") && has) INTV(0, 1000000, &ro.max_views);
        else if (!strcmp(a, "--max-obj") && has) INTV(0, SOOC_RENDER_MAX_COMP - 1, &ro.max_obj);
        else if (!strcmp(a, "--clip") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0.01, 1000, &ro.d_clip)) return 2;
        }
        else if (!strcmp(a, "--revisit")) ro.revisit = 1;
        else if (!strcmp(a, "--gate") && has) {
            /* three comma-separated numbers, each non-empty and in range (launch keys model.gate_*) */
            const char *g = argv[++i], *q = g;
            static const double lo[3] = {-1, -1, -1}, hi[3] = {1, 100, 1};
            int ok = 1;
            for (int t = 0; t < 3 && ok; t++) {
                char *e = NULL;
                ro.gate[t] = strtod(q, &e);
                ok = e != q && ro.gate[t] >= lo[t] && ro.gate[t] <= hi[t] && *e == (t < 2 ? ',' : '\0');
                q = e + 1;
            }
            if (!ok) {
                fprintf(stderr, "sooc3d eval: --gate wants MIN_RAYS,RATIO,PART (e.g. 0.02,0.5,0.4; 0 = default, -1 = off), "
                                "got '%s'\n", g);
                return 2;
            }
        }
        else if (!strcmp(a, "--merge") && has) {
            if (!sooc_cli_parse_merge(argv[++i], &ro.merge_radius)) {
                fprintf(stderr, "sooc3d eval: --merge wants a radius >= 0 in metres (0 = never merge)\n");
                return 2;
            }
        }
        else if (!strcmp(a, "--latents") && has) {
            if (!sooc_cli_parse_latents(argv[++i], &ro.latents)) {
                fprintf(stderr, "sooc3d eval: --latents wants mean or sample\n");
                return 2;
            }
        }
        else if (!strcmp(a, "--slots") && has) {
            if (!sooc_cli_parse_slots(argv[++i], &ro.slots)) {
                fprintf(stderr, "sooc3d eval: --slots wants 0 (the model's) up to %d object slots\n", SOOC_MODEL_K_MAX);
                return 2;
            }
        }
        else if (!strcmp(a, "--invalid-depth") && has) {
            int mode;
            if (sooc_model_invalid_depth_parse(argv[++i], &mode)) {
                fprintf(stderr, "sooc3d eval: --invalid-depth wants free or unknown\n");
                return 2;
            }
            ro.invalid_depth = 1 + mode;
        }
        else if (!strcmp(a, "--quiet")) quiet = 1;
        else if (!strcmp(a, "--query-every") && has) INTV(2, 1000000, &rel.query_every);
        else if (!strcmp(a, "--no-second-pass")) rel.second_pass = 0;
        else if (!strcmp(a, "--no-own-surface")) rel.own_surface = 0;
        else if (!strcmp(a, "--seen-tol") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], 0.001, 100, &rel.seen_tol)) return 2;
        } else if (!strcmp(a, "--seen-height") && has) {
            if (!sooc_cli_double_opt("eval", a, argv[++i], -100, 100, &rel.seen_height)) return 2;
        } else if (!strcmp(a, "--persist-min") && has) INTV(1, 1000000, &rel.persist_min);
        else if (!strcmp(a, "--panels") && has) panels = argv[++i];
        else {
            fprintf(stderr, "sooc3d eval: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
#undef INTV
    }
    if (!n_models || !n_dirs || !json || (n_names && n_names != n_models)) {
        if (n_names && n_names != n_models) fprintf(stderr, "sooc3d eval: give one --name per --model\n");
        usage(stderr);
        return 2;
    }
    if (!sooc_cli_framepath_check("eval", &fpp)) return 2;
    ro.timing = (sooc_eval_timing)timing;
    ro.birth = finetune && !no_birth ? &bp : NULL;   /* only the +ft rows birth */
    {   /* recorded sequences: cmd_eval_real.c, docs/metrics.md "Real sequences" */
        int n_rec = 0;
        for (int d = 0; d < n_dirs; d++) n_rec += sooc_eval_dir_is_recorded(dirs[d]);
        if (n_rec && n_rec != n_dirs) {
            fprintf(stderr, "sooc3d eval: --data mixes recorded sequences and `sooc3d gen` datasets; run them apart\n");
            return 2;
        }
        if (!n_rec && panels) {
            fprintf(stderr, "sooc3d eval: --panels applies to recorded sequences (use sooc3d render for gen scenes)\n");
            return 2;
        }
        if (n_rec) {
            if (runs != 1) { fprintf(stderr, "sooc3d eval: --runs applies to gen datasets only\n"); return 2; }
            char rn[MAX_MODELS][128];
            const char *rnp[MAX_MODELS];
            for (int i = 0; i < n_models; i++) {
                if (n_names) snprintf(rn[i], sizeof rn[i], "%s", names[i]);
                else model_name(models[i], rn[i], sizeof rn[i]);
                rnp[i] = rn[i];
            }
            rel.run = ro;
            rel.run.seed = seed;
            ftp.seed = seed;
            sooc_eval_real_cli rc = {models, rnp, n_models, dirs, n_dirs, json, md, rel, fpp, panels, quiet,
                                   finetune ? &ftp : NULL, geometric};
            return sooc_cmd_eval_real(&rc);
        }
    }

    sooc_status st = SOOC_OK;
    sooc_model *mdl[MAX_MODELS] = {0};
    char mname[MAX_MODELS][128], oname[MAX_MODELS][160], fname[MAX_MODELS][160];
    sooc_dataset *ds[MAX_DIRS] = {0};
    int *scale_of[MAX_DIRS] = {0};
    int n_sc[MAX_DIRS] = {0};
    sooc_eval_table *tab = NULL;
    sooc_frame *fr = NULL;
    sooc_gt_object *gt = NULL;
    sooc_scene scn;   /* the scene being scored: its true surfaces for the mesh metric */
    sooc_scene_init(&scn);
    double mesh_s = 0;
    long mesh_obj = 0, mesh_empty = 0;
    int fr_cap = 0, gt_cap = 0;
    char *text = NULL;
    int W = 0, H = 0;
    for (int i = 0; i < n_models; i++) {
        if ((st = sooc_model_load(&mdl[i], models[i], NULL, NULL))) goto fail;
        const sooc_model_config *c = sooc_model_get_config(mdl[i]);
        if (i == 0) W = c->img_w, H = c->img_h;
        else if (c->img_w != W || c->img_h != H) {
            st = sooc_seterr(SOOC_EINVAL, "%s: model resolution %dx%d differs from %s (%dx%d)", models[i], c->img_w,
                             c->img_h, models[0], W, H);
            goto fail;
        }
        if (n_names) snprintf(mname[i], sizeof mname[i], "%s", names[i]);
        else model_name(models[i], mname[i], sizeof mname[i]);
        snprintf(oname[i], sizeof oname[i], "%.127s online", mname[i]);
        snprintf(fname[i], sizeof fname[i], "%.127s+ft", mname[i]);
        if (geometric && !strcmp(mname[i], "geometric")) {
            st = sooc_seterr(SOOC_EINVAL, "a model is named 'geometric', the baseline's row: use --name");
            goto fail;
        }
        for (int j = 0; j < i; j++)
            if (!strcmp(mname[i], mname[j])) {
                st = sooc_seterr(SOOC_EINVAL, "two models are named '%s': use --name", mname[i]);
                goto fail;
            }
    }
    /* datasets and the scale of every scene */
    uint64_t total = 0;
    int total_scenes = 0;
    for (int d = 0; d < n_dirs; d++) {
        fpp.width = W, fpp.height = H;
        if ((st = sooc_dataset_open_fp(&ds[d], &dirs[d], 1, &fpp))) goto fail;
        n_sc[d] = sooc_dataset_n_scenes(ds[d]);
        if (max_scenes >= 0 && max_scenes < n_sc[d]) n_sc[d] = max_scenes;
        scale_of[d] = calloc(n_sc[d] ? (size_t)n_sc[d] : 1, sizeof(int));
        if (!scale_of[d]) { st = SOOC_ENOMEM; goto fail; }
        for (int s = 0; s < n_sc[d]; s++) {
            char path[1024];
            sooc_scene sc;
            sooc_scene_init(&sc);
            if ((st = sooc_path_join(path, sizeof path, sooc_dataset_scene_path(ds[d], s), "scene.yaml"))) goto fail;
            if ((st = sooc_scene_load(path, &sc))) goto fail;
            char scs[sizeof sc.scale + 1];
            snprintf(scs, sizeof scs, "%s", sc.scale);
            scale_of[d][s] = sooc_scale_parse(scs);
            sooc_scene_free(&sc);
            if (scale_of[d][s] < 0) {
                st = sooc_seterr(SOOC_EFORMAT, "%s: unknown scale '%s' (s, m, l, xl)", path, scs);
                goto fail;
            }
            int nv = sooc_dataset_n_views(ds[d], s), ni = sooc_dataset_n_inputs(ds[d], s);
            if (ro.max_views > 0 && ni > ro.max_views) nv -= ni - ro.max_views, ni = ro.max_views;
            total += (uint64_t)(nv + (timing == SOOC_EVAL_BOTH ? ni : 0)) * (uint64_t)n_models * (uint64_t)runs;
            if (finetune) total += (uint64_t)nv * (uint64_t)n_models * (uint64_t)runs;
            total_scenes++;
        }
    }
    if ((st = sooc_eval_table_create(&tab))) goto fail;
    {
        char note[1024], clip[64];
        if (ro.d_clip > 0) snprintf(clip, sizeof clip, "%g m (--clip)", ro.d_clip);
        else snprintf(clip, sizeof clip, "%g m (the model's)", (double)(sooc_model_get_config(mdl[0])->d_clip * sooc_model_get_config(mdl[0])->unit_m));
        snprintf(note, sizeof note,
                 "%s Mean +- std over %d run%s (seeds %llu..%llu), %d scene%s; %d+%d samples per ray; "
                 "RGB RMSE sums the channels (MulMON); L2 in metres for query views; clip depth %s.",
                 sooc_eval_timing_note(ro.timing), runs, runs > 1 ? "s" : "", (unsigned long long)seed,
                 (unsigned long long)(seed + (uint64_t)runs - 1), total_scenes, total_scenes == 1 ? "" : "s",
                 ro.n_coarse, ro.n_fine, clip);
        if ((st = sooc_eval_table_set_note(tab, note))) goto fail;
    }
    prog_ctx pc;
    memset(&pc, 0, sizeof pc);
    pc.total = total;
    pc.quiet = quiet;
    pc.t0 = sooc_seconds();
    if (!quiet) sooc_progress_begin(&pc.pr, "eval", total);
    double upd_s = 0, ren_s = 0, ft_s = 0;
    long n_born = 0, n_pruned = 0;
    long n_upd = 0;
    for (int d = 0; d < n_dirs; d++) {
        for (int s = 0; s < n_sc[d]; s++) {
            int nv = sooc_dataset_n_views(ds[d], s), no = sooc_dataset_n_objects(ds[d], s);
            if (nv > fr_cap) {
                free(fr);
                fr_cap = nv;
                if (!(fr = malloc((size_t)nv * sizeof *fr))) { st = SOOC_ENOMEM; goto fail; }
            }
            if (no > gt_cap) {
                free(gt);
                gt_cap = no;
                if (!(gt = malloc((size_t)no * sizeof *gt))) { st = SOOC_ENOMEM; goto fail; }
            }
            for (int v = 0; v < nv; v++) fr[v] = *sooc_dataset_view(ds[d], s, v);
            for (int i = 0; i < no; i++) sooc_dataset_object(ds[d], s, i, &gt[i].id, &gt[i].x, &gt[i].z);
            int scale = scale_of[d][s];
            ro.scene = NULL;
            if (mesh_res > 0) {
                char sp[1024];
                sooc_scene_free(&scn);
                if ((st = sooc_path_join(sp, sizeof sp, sooc_dataset_scene_path(ds[d], s), "scene.yaml")) ||
                    (st = sooc_scene_load(sp, &scn)))
                    goto fail;
                ro.scene = &scn, ro.mesh_res = mesh_res;
            }
            if (geometric) {   /* the baseline: deterministic, one run */
                const sooc_model_config *c0 = sooc_model_get_config(mdl[0]);
                sooc_eval_scene_result res;
                st = sooc_eval_geometric_scene(fr, nv, gt, no, NULL, ro.d_clip > 0 ? ro.d_clip : c0->d_clip * c0->unit_m,
                                               &res);
                if (st) {
                    sooc_adderr(st, "%s", sooc_dataset_scene_path(ds[d], s));
                    goto fail;
                }
                for (int r = 0; r < runs; r++)
                    if ((st = sooc_eval_table_add_sums(tab, "geometric", scale, r, 0, &res.input_final)) ||
                        (st = sooc_eval_table_add_sums(tab, "geometric", scale, r, 1, &res.query)))
                        goto fail;
            }
            for (int mi = 0; mi < n_models; mi++) {
                for (int r = 0; r < runs; r++) {
                    /* A long model name may be cut: this is only the progress line. */
                    if (snprintf(pc.extra, sizeof pc.extra, "%s  %s scene %d/%d  run %d/%d", mname[mi],
                                 sooc_scale_name(scale), s + 1, n_sc[d], r + 1, runs) >= (int)sizeof pc.extra)
                        pc.extra[sizeof pc.extra - 1] = 0;
                    ro.seed = seed + (uint64_t)r;
                    sooc_eval_scene_result res;
                    st = sooc_eval_run_scene(mdl[mi], fr, nv, gt, no, &ro, on_view, NULL, &pc, &res);
                    if (st) {
                        sooc_adderr(st, "%s", sooc_dataset_scene_path(ds[d], s));
                        goto fail;
                    }
                    upd_s += res.update_s;
                    mesh_s += res.mesh_s, mesh_obj += res.mesh_objects, mesh_empty += res.mesh_empty;
                    ren_s += res.render_s;
                    n_upd += res.n_mapped;
                    if (ro.timing & SOOC_EVAL_FINAL) {
                        if ((st = sooc_eval_table_add_sums(tab, mname[mi], scale, r, 0, &res.input_final))) goto fail;
                        if ((st = sooc_eval_table_add_sums(tab, mname[mi], scale, r, 1, &res.query))) goto fail;
                    }
                    if (ro.timing & SOOC_EVAL_ONLINE) {
                        const char *nm = ro.timing == SOOC_EVAL_BOTH ? oname[mi] : mname[mi];
                        if ((st = sooc_eval_table_add_sums(tab, nm, scale, r, 0, &res.input_online))) goto fail;
                        if ((st = sooc_eval_table_add_sums(tab, nm, scale, r, 1, &res.query))) goto fail;
                    }
                    if (finetune && !sooc_model_is_global(mdl[mi])) {   /* the <name>+ft row */
                        sooc_eval_run_opts rf = ro;
                        rf.finetune = &ftp;
                        rf.timing = SOOC_EVAL_FINAL;
                        ftp.seed = ro.seed;
                        st = sooc_eval_run_scene(mdl[mi], fr, nv, gt, no, &rf, on_view, NULL, &pc, &res);
                        if (st) {
                            sooc_adderr(st, "%s (finetuned)", sooc_dataset_scene_path(ds[d], s));
                            goto fail;
                        }
                        ren_s += res.render_s;
                        ft_s += res.finetune_s;
                        n_born += res.n_born, n_pruned += res.n_pruned;
                        if ((st = sooc_eval_table_add_sums(tab, fname[mi], scale, r, 0, &res.input_final))) goto fail;
                        if ((st = sooc_eval_table_add_sums(tab, fname[mi], scale, r, 1, &res.query))) goto fail;
                    }
                }
            }
        }
    }
    double el = sooc_seconds() - pc.t0;
    if (!quiet) {
        char extra[128];
        snprintf(extra, sizeof extra, "%.1f s", el);
        sooc_progress_end(&pc.pr, extra);
    }
    if ((st = sooc_eval_table_text(tab, &text))) goto fail;
    printf("%s", text);
    {
        char rows[3 * MAX_MODELS + 1][160];
        int nr = 0, used[SOOC_N_SCALES] = {0};
        for (int d = 0; d < n_dirs; d++)
            for (int s = 0; s < n_sc[d]; s++) used[scale_of[d][s]] = 1;
        for (int i = 0; i < n_models; i++) {
            if (ro.timing & SOOC_EVAL_FINAL) snprintf(rows[nr++], sizeof rows[0], "%.150s", mname[i]);
            if (ro.timing & SOOC_EVAL_ONLINE)
                snprintf(rows[nr++], sizeof rows[0], "%.150s", ro.timing == SOOC_EVAL_BOTH ? oname[i] : mname[i]);
            if (finetune && !sooc_model_is_global(mdl[i])) snprintf(rows[nr++], sizeof rows[0], "%.150s", fname[i]);
        }
        if (geometric) snprintf(rows[nr++], sizeof rows[0], "geometric");
        print_supp(tab, rows, nr, used, runs);
        print_geom(tab, rows, nr, used, runs);
    }
    printf("\neval: %d scene%s x %d model%s x %d run%s, %llu views in %.1f s (%.2f views/s); "
           "mapper %.1f ms/update, rendering + scoring %.1f s\n",
           total_scenes, total_scenes == 1 ? "" : "s", n_models, n_models == 1 ? "" : "s", runs, runs == 1 ? "" : "s",
           (unsigned long long)pc.done, el, el > 0 ? (double)pc.done / el : 0.0, n_upd ? 1e3 * upd_s / (double)n_upd : 0.0,
           ren_s);
    if (finetune) {
        printf("eval: finetuning (+ft rows) %.1f s in all", ft_s);
        if (ro.birth) printf(", %ld entries born before it, %ld entries removed after it (no density)", n_born, n_pruned);
        printf("\n");
    }
    if (mesh_res > 0)
        printf("eval: mesh metric (base rows) over %ld matched objects (%ld more with an empty mesh), %d^3 per box, "
               "%.1f s\n", mesh_obj, mesh_empty, mesh_res, mesh_s);
    if ((st = sooc_eval_table_write(tab, json, md))) goto fail;
    printf("eval: wrote %s%s%s\n", json, md ? " and " : "", md ? md : "");
    sooc_free(text);
    text = NULL;
fail:
    sooc_scene_free(&scn);
    sooc_free(text);
    free(fr);
    free(gt);
    sooc_eval_table_destroy(tab);
    for (int d = 0; d < n_dirs; d++) {
        sooc_dataset_destroy(ds[d]);
        free(scale_of[d]);
    }
    for (int i = 0; i < n_models; i++) sooc_model_destroy(mdl[i]);
    return st ? sooc_cli_fail("eval", st) : 0;
}
