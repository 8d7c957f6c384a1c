/* sooc3d finetune: per-object NeRF finetuning by EM of a stored map
 * (include/sooc3d/train.h, docs/finetune.md). Every finished object / layout
 * block is committed to the map database in its own transaction; Ctrl-C stops
 * at the next progress report with the database consistent, and a second run
 * skips what is stored and finetunes the rest. */
#include "cli.h"
#include "sooc3d/train.h"
#include "sooc3d/frame.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/model.h"

#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static volatile sig_atomic_t g_stop;
static void on_sigint(int sig) {
    (void)sig;
    g_stop = 1;
}

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d finetune --map DB --model M --seq DIR [--iterations N] [--rays N] [--lr X]\n"
            "                       [--lr-z X] [--lr-final F] [--support M] [--no-layout] [--restart] [--seed S]\n"
            "                       [--every K] [--quiet] [--max-views N] [--no-birth] [--birth-margin U] [frame-path options]\n\n"
            "Per-object NeRF finetuning by EM (docs/finetune.md): every object of the map DB\n"
            "gets its own copy of the model's object decoder and a free z^what (z^where fixed), every\n"
            "layout block its own layout decoder and latent; each is fitted by Adam to the responsibility-\n"
            "weighted likelihood of the rays of the keyframes that saw it (the views stored in the map's\n"
            "keyframes table, read again from DIR; all posed input frames if the map has none). Each\n"
            "finished object is stored in DB in its own transaction (schema version 2; a version-1 map\n"
            "is migrated). render, eval, map export and the node use the finetuned decoders from then on.\n"
            "Ctrl-C stops cleanly (exit 130); running again skips the stored objects.\n\n"
            "  --map         map database (written by sooc3d node, or by any map writer)\n"
            "  --model       the model the map was built with (models/<name>/model.bin)\n"
            "  --seq         the sequence the map was built from\n"
            "  --iterations  Adam steps per object / block (default %d)\n"
            "  --rays        rays per step (default %d)\n"
            "  --lr, --lr-z  Adam learning rates of the decoder weights and of z^what (default %g, %g)\n"
            "  --lr-final F  both rates fall by a half cosine over each unit's steps to F times their\n"
            "                start (default 1: constant)\n"
            "  --support M   surfaces within M metres of the support plane are the layout's: objects\n"
            "                are kept empty there (default 0: off; docs/finetune.md \"The support plane\")\n"
            "  --no-layout   do not finetune the layout blocks\n"
            "  --restart     delete the stored finetuned decoders first and start over\n"
            "  --max-views   use at most N views (evenly spread; 0 = all)\n"
            "  --every       progress line every K steps (default 20)\n"
            "  --no-birth    no births and deaths. By default a run that starts with nothing finetuned\n"
            "                first adds entries where the views show a surface the map does not draw\n"
            "                (objects online inference missed; stored in DB in one transaction), and\n"
            "                once every unit is stored, removes the entries (born or not) whose\n"
            "                density is empty (docs/finetune.md \"Births and deaths\")\n"
            "  --birth-margin U  how far (model units) the rendered surface must lie behind the\n"
            "                sensor's for a pixel to count as unexplained (default 0.15)\n"
            "%s",
            300, 512, 1e-3, 1e-3, sooc_cli_framepath_help);
}

/* View k of the nv views (keyframe or frame numbers) into *f; *use = 0 when
 * --max-views skips it or it has no pose or is a query view. */
static sooc_status read_view(sooc_framepath *sq, const int64_t *views, size_t nv, size_t k, int max_views, int64_t nf,
                             const char *db, const char *seq, sooc_frame *f, int *use) {
    *use = 0;
    if (max_views > 0 && nv > (size_t)max_views && (k * (size_t)max_views) / nv == ((k + 1) * (size_t)max_views) / nv)
        return SOOC_OK;
    if (views[k] < 0 || views[k] >= nf)
        return sooc_seterr(SOOC_EINVAL, "%s: keyframe view %lld is not a frame of %s (%lld frames): wrong --seq?", db,
                           (long long)views[k], seq, (long long)nf);
    sooc_status st = sooc_framepath_read(sq, views[k], f);
    if (st) return st;
    *use = f->has_pose && !f->is_query;
    return SOOC_OK;
}

typedef struct prog_ctx {
    int quiet;
    const char *what;
    double t0;
} prog_ctx;

static int on_progress(void *user, const sooc_finetune_progress *p) {
    prog_ctx *c = user;
    if (!c->quiet)
        fprintf(stderr, "\rfinetune [%d/%d] %s: step %d/%d loss %.4f %.1f steps/s ETA %.0f s   ", p->unit + 1,
                p->n_units, c->what, p->iter, p->iterations, p->loss, p->steps_per_s, p->eta_s);
    return g_stop != 0;
}

int sooc_cmd_finetune(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *db = NULL, *model = NULL, *seq = NULL;
    int quiet = 0, restart = 0, every = 20, max_views = 0, birth = 1;
    sooc_birth_params bp;
    sooc_birth_params_default(&bp);
    sooc_finetune_params fp;
    sooc_finetune_params_default(&fp);
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    int fo;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
        double d;
        if (!strcmp(a, "--map") && has) db = argv[++i];
        else if (!strcmp(a, "--model") && has) model = argv[++i];
        else if (!strcmp(a, "--seq") && has) seq = argv[++i];
        else if (!strcmp(a, "--iterations") && has) {
            if (!sooc_cli_int_opt("finetune", a, argv[++i], 0, 1000000, &fp.iterations)) return 2;
        } else if (!strcmp(a, "--rays") && has) {
            if (!sooc_cli_int_opt("finetune", a, argv[++i], 1, 1 << 20, &fp.rays)) return 2;
        } else if (!strcmp(a, "--lr") && has) {
            if (!sooc_cli_double_opt("finetune", a, argv[++i], 0, 1, &d)) return 2;
            fp.lr = (float)d;
        } else if (!strcmp(a, "--lr-z") && has) {
            if (!sooc_cli_double_opt("finetune", a, argv[++i], 0, 1, &d)) return 2;
            fp.lr_z = (float)d;
        } else if (!strcmp(a, "--lr-final") && has) {
            if (!sooc_cli_double_opt("finetune", a, argv[++i], 0, 1, &d)) return 2;
            fp.lr_final = (float)d;
        } else if (!strcmp(a, "--support") && has) {
            if (!sooc_cli_double_opt("finetune", a, argv[++i], 0, 1, &d)) return 2;
            fp.support_m = (float)d;
        } else if (!strcmp(a, "--seed") && has) {
            if (!sooc_cli_u64_opt("finetune", a, argv[++i], UINT64_MAX, &fp.seed)) return 2;
        } else if (!strcmp(a, "--every") && has) {
            if (!sooc_cli_int_opt("finetune", a, argv[++i], 1, 1000000, &every)) return 2;
        } else if (!strcmp(a, "--max-views") && has) {
            if (!sooc_cli_int_opt("finetune", a, argv[++i], 0, 1000000, &max_views)) return 2;
        } else if (!strcmp(a, "--no-layout")) fp.layout = 0;
        else if (!strcmp(a, "--restart")) restart = 1;
        else if (!strcmp(a, "--no-birth")) birth = 0;
        else if (!strcmp(a, "--birth-margin") && has) {
            if (!sooc_cli_double_opt("finetune", a, argv[++i], 1e-3, 100, &d)) return 2;
            bp.depth_margin = (float)d;
        }
        else if (!strcmp(a, "--quiet")) quiet = 1;
        else if ((fo = sooc_cli_framepath_opt("finetune", argc, argv, &i, &fpp)) != 0) {
            if (fo < 0) return 2;
        } else {
            fprintf(stderr, "sooc3d finetune: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
    }
    if (!db || !model || !seq) {
        usage(stderr);
        return 2;
    }
    if (!sooc_cli_framepath_check("finetune", &fpp)) return 2;

    sooc_status st;
    sooc_model *m = NULL;
    sooc_mapstore *ms = NULL;
    sooc_cogmap *map = NULL;
    sooc_framepath *sq = NULL;
    sooc_finetune *ft = NULL;
    int64_t *views = NULL;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    int interrupted = 0;
    if ((st = sooc_model_load(&m, model, NULL, NULL))) goto fail;
    const sooc_model_config *mc = sooc_model_get_config(m);
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    mp.dim = mc->d_what, mp.layout_dim = mc->d_layout;
    if ((st = sooc_mapstore_open(&ms, db, &mp))) goto fail;
    if (restart && (st = sooc_mapstore_ft_clear(ms))) goto fail;
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = mc->d_what, cp.layout_dim = mc->d_layout, cp.block_size = (double)mc->block_size * mc->unit_m;
    if ((st = sooc_cogmap_create(&map, &cp))) goto fail;
    if ((st = sooc_mapstore_load_map(ms, map))) goto fail;

    /* the views: the map's keyframes, else every posed input frame */
    sooc_cli_framepath_model(&fpp, mc);
    fpp.map_db = db;
    if ((st = sooc_framepath_open(&sq, seq, &fpp))) goto fail;
    int64_t nf = sooc_framepath_count(sq);
    size_t nv = 0;
    if ((st = sooc_mapstore_keyframe_views(ms, NULL, 0, &nv))) goto fail;
    int from_kf = nv > 0;
    if (!from_kf) nv = (size_t)nf;
    views = malloc((nv ? nv : 1) * sizeof *views);
    if (!views) {
        st = SOOC_ENOMEM;
        goto fail;
    }
    if (from_kf) {
        if ((st = sooc_mapstore_keyframe_views(ms, views, nv, &nv))) goto fail;
    } else {
        for (size_t i = 0; i < nv; i++) views[i] = (int64_t)i;
    }
    uint64_t n_obj = 0, n_blk = 0;
    if ((st = sooc_mapstore_ft_count(ms, &n_obj, &n_blk))) goto fail;
    /* births: once, before the first unit is stored (a resumed run does not birth again) */
    int n_born = 0, pruned = 0;
    uint64_t born_ids[256];
    if (birth && !n_obj && !n_blk) {
        sooc_birth *b = NULL;
        if ((st = sooc_birth_create(&b, m, map, &bp, 0))) goto fail;
        size_t bv = 0;
        for (size_t k = 0; k < nv && !st; k++) {
            int use = 0;
            if (!(st = read_view(sq, views, nv, k, max_views, nf, db, seq, &f, &use)) && use) {
                st = sooc_birth_add_view(b, &f);
                bv++;
            }
        }
        if (!st && bp.max_births > 256) bp.max_births = 256;
        if (!st) st = sooc_birth_run(b, born_ids, 256, &n_born);
        size_t npts = sooc_birth_n_points(b);
        sooc_birth_destroy(b);
        if (st) goto fail;
        if (n_born) {   /* the new entries go into the DB in one transaction */
            sooc_cogmap_entry be[256];
            for (int k = 0; k < n_born && !st; k++) st = sooc_cogmap_get(map, born_ids[k], &be[k]);
            if (!st && !(st = sooc_mapstore_begin(ms))) {
                if (!(st = sooc_mapstore_put_entries(ms, be, (size_t)n_born)) &&
                    !(st = sooc_mapstore_set_next_id(ms, sooc_cogmap_next_id(map))))
                    st = sooc_mapstore_commit(ms);
                if (st) sooc_mapstore_rollback(ms);
            }
            if (st) goto fail;
        }
        if (!quiet)
            printf("finetune: births: %zu unexplained surface points in %zu views, %d new entries\n",
                   npts, bv, n_born);
    }
    if ((st = sooc_finetune_create(&ft, m, map, &fp))) goto fail;
    size_t used = 0;
    for (size_t k = 0; k < nv; k++) {
        int use = 0;
        if ((st = read_view(sq, views, nv, k, max_views, nf, db, seq, &f, &use))) goto fail;
        if (!use) continue;
        if ((st = sooc_finetune_add_view(ft, &f))) goto fail;
        used++;
    }
    int nu = sooc_finetune_n_units(ft);
    if (!quiet)
        printf("finetune: %s: %zu entries, %zu views (%s), %d units (objects, then layout blocks); %llu objects and "
               "%llu blocks already finetuned\n",
               db, sooc_cogmap_count(map), used, from_kf ? "keyframes" : "all posed frames", nu,
               (unsigned long long)n_obj, (unsigned long long)n_blk);
    void (*old)(int) = signal(SIGINT, on_sigint);
    double t0 = sooc_seconds();
    int done = 0, skipped = 0;
    for (int u = 0; u < nu && !st; u++) {
        sooc_finetune_unit un;
        if ((st = sooc_finetune_unit_get(ft, u, &un))) break;
        int is_blk = un.kind == SOOC_FT_LAYOUT, found = 0;
        if ((st = sooc_mapstore_ft_get(ms, is_blk, un.id, un.bi, un.bj, &found, NULL, NULL))) break;
        if (found) {
            skipped++;
            continue;
        }
        if (g_stop) {
            interrupted = 1;
            break;
        }
        char what[96];
        if (is_blk) snprintf(what, sizeof what, "layout block (%d, %d)", un.bi, un.bj);
        else snprintf(what, sizeof what, "object %llu", (unsigned long long)un.id);
        prog_ctx pc = {quiet, what, sooc_seconds()};
        sooc_finetune_result res;
        st = sooc_finetune_unit_run(ft, u, on_progress, &pc, every, &res);
        if (st == SOOC_EINTERRUPTED) {
            sooc_clearerr();
            st = SOOC_OK;
            interrupted = 1;
            break;
        }
        if (st) break;
        const float *v = NULL;
        size_t n = 0;
        if ((st = sooc_finetune_unit_payload(ft, u, &v, &n))) break;
        if ((st = sooc_mapstore_ft_put(ms, is_blk, un.id, un.bi, un.bj, v, n, res.steps, res.loss_last))) break;
        done++;
        if (!quiet)
            fprintf(stderr, "\rfinetune [%d/%d] %s: %d steps, %zu rays in %d views, loss %.4f -> %.4f, %.1f s%*s\n",
                    u + 1, nu, what, res.steps, un.n_rays, un.n_views, res.loss_first, res.loss_last, res.seconds, 12,
                    "");
    }
    signal(SIGINT, old);
    if (st) goto fail;
    /* deaths: once every unit is stored, the entries whose finetuned density
     * reaches the surface level nowhere are removed (docs/finetune.md "Births and deaths") */
    if (birth && !interrupted) {
        uint64_t *gone = NULL;
        st = sooc_birth_prune_all(m, map, &gone, &pruned);
        if (!st && pruned) st = sooc_mapstore_remove_entries(ms, gone, (size_t)pruned);
        sooc_free(gone);
        if (st) goto fail;
    }
    printf("finetune: %d finetuned and stored, %d already stored, %d left%s (%.1f s)\n", done, skipped,
           nu - done - skipped, interrupted ? " (interrupted: run again to continue)" : "", sooc_seconds() - t0);
    if (birth && (n_born || pruned))
        printf("finetune: %d entries born, %d entries removed (no density after finetuning)\n", n_born, pruned);
    sooc_frame_free(&f);
    free(views);
    sooc_finetune_destroy(ft);
    sooc_framepath_close(sq);
    sooc_cogmap_destroy(map);
    sooc_mapstore_close(ms);
    sooc_model_destroy(m);
    return interrupted ? 130 : 0;
fail:
    sooc_frame_free(&f);
    free(views);
    sooc_finetune_destroy(ft);
    sooc_framepath_close(sq);
    sooc_cogmap_destroy(map);
    sooc_mapstore_close(ms);
    sooc_model_destroy(m);
    return sooc_cli_fail("finetune", st);
}
