/* The training loop: curriculum, Adam with clipping, temperature and KL
 * schedules, checkpoints with exact resume, validation and logs. */
#include "sooc3d/train.h"
#include "sooc3d/model.h"
#include "sooc3d/eval.h"
#include "nn/nn.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define TRAINER_MAGIC 0x4e525453434f4f53ULL /* "SOOCSTRN" */
#define TRAINER_VERSION 1u

/* Trainer state stored in the checkpoint's trainer blob, followed by the Adam
 * moments m and v (n_params floats each). */
typedef struct trainer_blob {
    uint64_t magic;
    uint32_t version;
    uint32_t batch;           /* scenes per step over all ranks (ranks x accum; 0 = not recorded) */
    int64_t step;             /* next step to run                      */
    int64_t adam_t;
    uint64_t n_params;
    uint64_t seed;
    double best_val;          /* best validation mIoU (-1 = none yet)  */
    int64_t best_step;
    int64_t skipped;          /* steps skipped for non-finite values   */
} trainer_blob;

typedef struct trainer {
    const sooc_train_config *cfg;
    const sooc_train_run_params *rp;
    sooc_model *model;
    sooc_model_ws *ws;        /* the trainer runs the model: its workspace */
    sooc_nn_params adam;      /* wraps the model's slabs               */
    sooc_nn_param_view view;
    float *m, *v;
    float *gacc;              /* accum > 1: the step's gradient sum (each scene's gradient
                                 is computed alone in the model's slab, then added here) */
    size_t n;
    trainer_blob st;
    uint8_t *idbits;          /* 65536-bit scratch for counting ids    */
    int rank, size;           /* data parallelism (include/sooc3d/model.h) */
    double t_val, t_ckpt;     /* seconds in validation / checkpoints since the last log row */
    char path_last[4096], path_best[4096], path_log[4096], path_val[4096], path_png[4096];
} trainer;

static float tau_at(const sooc_train_config *c, int64_t s) {
    double a = c->tau_frac > 0 ? (double)s / ((double)c->tau_frac * (double)c->steps) : 1.0;
    if (a > 1) a = 1;
    return (float)(c->tau_start + (c->tau_end - c->tau_start) * a);
}

static void curriculum(const sooc_train_config *c, int64_t s, sooc_rng *rng, int *T, int *Q) {
    double f = (double)s / (double)c->steps;
    if (f < c->phase_a) {
        *T = 1;
        *Q = c->q_a;
    } else if (f < c->phase_b) {
        *T = c->t_min_b + (int)sooc_rng_below(rng, (uint32_t)(c->t_max_b - c->t_min_b + 1));
        *Q = c->q_bc;
    } else {
        *T = c->t_min_c + (int)sooc_rng_below(rng, (uint32_t)(c->t_max_c - c->t_min_c + 1));
        *Q = c->q_bc;
    }
}

/* Mean number of distinct visible GT objects per view (instance id != 0). */
static double visible_objects(trainer *tr, const sooc_frame *v, int T) {
    double sum = 0;
    for (int t = 0; t < T; t++) {
        if (!v[t].instance) continue;
        memset(tr->idbits, 0, 65536 / 8);
        int n = 0, np = v[t].width * v[t].height;
        for (int i = 0; i < np; i++) {
            uint16_t id = v[t].instance[i];
            if (id && !(tr->idbits[id >> 3] & (1u << (id & 7)))) {
                tr->idbits[id >> 3] |= (uint8_t)(1u << (id & 7));
                n++;
            }
        }
        sum += n;
    }
    return T ? sum / T : 0;
}

static sooc_status save_ckpt(trainer *tr, const char *path) {
    size_t blob_n = sizeof(trainer_blob) + 2 * tr->n * sizeof(float);
    uint8_t *blob = sooc_malloc(blob_n);
    if (!blob) return SOOC_ENOMEM;
    tr->st.adam_t = tr->adam.adam_t;
    memcpy(blob, &tr->st, sizeof tr->st);
    memcpy(blob + sizeof tr->st, tr->m, tr->n * sizeof(float));
    memcpy(blob + sizeof tr->st + tr->n * sizeof(float), tr->v, tr->n * sizeof(float));
    sooc_status s = sooc_model_save(tr->model, path, blob, blob_n);
    sooc_free(blob);
    return s;
}

static sooc_status restore_blob(trainer *tr, const void *blob, size_t n) {
    trainer_blob b;
    if (!blob || n < sizeof b)
        return sooc_seterr(SOOC_EFORMAT, "%s: no trainer state in the checkpoint", tr->path_last);
    memcpy(&b, blob, sizeof b);
    if (b.magic != TRAINER_MAGIC || b.version != TRAINER_VERSION)
        return sooc_seterr(SOOC_EVERSION, "%s: trainer state has magic/version %llx/%u, expected %llx/%u",
                           tr->path_last, (unsigned long long)b.magic, b.version,
                           (unsigned long long)TRAINER_MAGIC, TRAINER_VERSION);
    if (b.n_params != tr->n || n != sizeof b + 2 * tr->n * sizeof(float))
        return sooc_seterr(SOOC_EFORMAT, "%s: trainer state is for %llu parameters, the model has %zu",
                           tr->path_last, (unsigned long long)b.n_params, tr->n);
    if (b.seed != tr->cfg->seed)
        return sooc_seterr(SOOC_EINVAL, "%s: checkpoint was trained with seed %llu, the config says %llu",
                           tr->path_last, (unsigned long long)b.seed, (unsigned long long)tr->cfg->seed);
    uint64_t batch = (uint64_t)sooc_dist_size() * (uint64_t)tr->cfg->accum;
    if (b.batch && b.batch != batch)
        sooc_log(SOOC_LOG_WARN, "%s: trained with %u scenes per step over all ranks, now %llu (ranks x accum): "
                                "the data order from here on differs from an uninterrupted run",
                 tr->path_last, b.batch, (unsigned long long)batch);
    tr->st = b;
    tr->adam.adam_t = b.adam_t;
    memcpy(tr->m, (const uint8_t *)blob + sizeof b, tr->n * sizeof(float));
    memcpy(tr->v, (const uint8_t *)blob + sizeof b + tr->n * sizeof(float), tr->n * sizeof(float));
    return SOOC_OK;
}

/* Keep only the rows of a CSV log whose step (first column) is below `step`,
 * so that a resumed run does not log the same steps twice. */
static sooc_status trim_log(const char *path, int64_t step) {
    if (!sooc_file_exists(path)) return SOOC_OK;
    char *buf = NULL;
    size_t n = 0;
    sooc_status s = sooc_file_read_all(path, (size_t)1 << 30, (void **)&buf, &n);
    if (s) return s;
    size_t keep = 0;
    char *line = buf;
    int first = 1;
    while (line < buf + n) {
        char *nl = memchr(line, '\n', (size_t)(buf + n - line));
        char *end = nl ? nl + 1 : buf + n;
        if (!first && strtoll(line, NULL, 10) >= step) break;
        first = 0;
        keep = (size_t)(end - buf);
        line = end;
    }
    if (keep != n) s = sooc_file_write_atomic(path, buf, keep);
    sooc_free(buf);
    return s;
}

static sooc_status append_line(const char *path, const char *header, const char *line) {
    int exists = sooc_file_exists(path);
    FILE *f = fopen(path, "a");
    if (!f) return sooc_seterr(SOOC_EIO, "%s: cannot open for appending", path);
    if (!exists) fputs(header, f);
    fputs(line, f);
    if (fclose(f) != 0) return sooc_seterr(SOOC_EIO, "%s: write failed", path);
    return SOOC_OK;
}

static sooc_status copy_config(const char *src, const char *out_dir) {
    if (!src) return SOOC_OK;
    void *buf;
    size_t n;
    char dst[4096];
    sooc_status s = sooc_path_join(dst, sizeof dst, out_dir, "config.yaml");
    if (!s) s = sooc_file_read_all(src, 1 << 20, &buf, &n);
    if (s) return s;
    s = sooc_file_write_atomic(dst, buf, n);
    sooc_free(buf);
    return s;
}

static sooc_status run_validation(trainer *tr, int64_t step) {
    const sooc_train_run_params *rp = tr->rp;
    if (!rp->val_fn || !rp->val) return SOOC_OK;
    double miou = NAN, miou_in = NAN, l2 = NAN, t0 = sooc_seconds();
    sooc_status s = rp->val_fn(rp->val_user, tr->model, rp->val, &miou, &miou_in, &l2);
    if (s) return sooc_adderr(s, "validation at step %lld", (long long)step);
    char line[256];
    snprintf(line, sizeof line, "%lld,%.5f,%.5f,%.4f,%.1f\n", (long long)step, miou, miou_in, l2,
             sooc_seconds() - t0);
    s = append_line(tr->path_val, "step,val_miou_query,val_miou_input,val_l2,seconds\n", line);
    if (s) return s;
    sooc_log(SOOC_LOG_INFO, "step %lld: validation query mIoU %.4f (input %.4f, L2 %.3f m)", (long long)step,
             miou, miou_in, l2);
    if (isfinite(miou) && miou > tr->st.best_val) {
        tr->st.best_val = miou;
        tr->st.best_step = step;
        s = save_ckpt(tr, tr->path_best);
        if (s) return s;
        sooc_log(SOOC_LOG_INFO, "new best checkpoint %s (mIoU %.4f)", tr->path_best, miou);
    }
    return SOOC_OK;
}

/* Fine-tuning: copy the weights of checkpoint `path` into the fresh model m.
 * Everything that shapes the parameter slab must agree, except that a
 * checkpoint with fewer slots than the config's K is widened first (its added
 * slot priors are mirrored learnt ones); the rest (clip depth, likelihood
 * constants, prior spread at init) is the config's. */
static sooc_status init_from(sooc_model *m, const sooc_model_config *mc, const char *path) {
    sooc_model *src;
    sooc_status s = sooc_model_load(&src, path, NULL, NULL);
    if (s) return sooc_adderr(s, "train --init");
    const sooc_model_config *c = sooc_model_get_config(src);
    if (c->K < mc->K && !c->global_frame) {   /* more slots: the added priors mirror learnt ones */
        sooc_model *w;
        int K0 = c->K;
        s = sooc_model_copy_slots(src, mc->K, &w);
        sooc_model_destroy(src);   /* c pointed into it */
        if (s) return sooc_adderr(s, "train --init %s", path);
        sooc_log(SOOC_LOG_INFO, "%s: %d slots widened to the config's %d (sooc_model_copy_slots)", path, K0, mc->K);
        src = w;
        c = sooc_model_get_config(src);
    }
    const char *bad = c->K != mc->K ? "K" : c->d_what != mc->d_what ? "d_what" : c->d_layout != mc->d_layout ? "d_layout"
                    : c->img_w != mc->img_w || c->img_h != mc->img_h ? "img_w/img_h"
                    : c->dec_width != mc->dec_width ? "dec_width" : c->dec_color_width != mc->dec_color_width ? "dec_color_width"
                    : c->n_freq != mc->n_freq ? "n_freq" : c->n_freq_layout != mc->n_freq_layout ? "n_freq_layout"
                    : memcmp(c->ref_ch, mc->ref_ch, sizeof c->ref_ch) ? "ref_ch" : c->ref_fc != mc->ref_fc ? "ref_fc"
                    : c->ref_hidden != mc->ref_hidden ? "ref_hidden" : c->global_frame != mc->global_frame ? "global_frame"
                    : sooc_model_param_count(src) != sooc_model_param_count(m) ? "parameter count" : NULL;
    if (bad) {
        sooc_model_destroy(src);
        return sooc_seterr(SOOC_EINVAL, "%s: its %s differs from the config's model; --init needs the same network shapes",
                           path, bad);
    }
    memcpy(sooc_model_params(m), sooc_model_params(src), sooc_model_param_count(m) * sizeof(float));
    sooc_model_destroy(src);
    sooc_log(SOOC_LOG_INFO, "weights from %s (fine-tuning)", path);
    return SOOC_OK;
}

/* Data parallelism: every rank must hold the same network before the first
 * step. Rank 0's parameter count is checked on every rank, then its trainer
 * state (step, Adam step, best validation), weights and Adam moments are
 * broadcast, so the ranks agree even when only rank 0 could read last.bin. */
static sooc_status sync_ranks(trainer *tr) {
    uint64_t n0 = tr->n;
    sooc_status s = sooc_dist_bcast(&n0, sizeof n0, "parameter count");
    if (s) return s;
    double bad = n0 != tr->n;
    if ((s = sooc_dist_sum_f64(&bad, 1, "parameter count check"))) return s;
    if (bad > 0)
        return sooc_seterr(SOOC_EINVAL, "rank %d: the model has %zu parameters, rank 0's %llu (%g rank(s) differ): "
                                        "every rank needs the same config and checkpoint",
                           tr->rank, tr->n, (unsigned long long)n0, bad);
    if ((s = sooc_dist_bcast(&tr->st, sizeof tr->st, "trainer state")) ||
        (s = sooc_dist_bcast(sooc_model_params(tr->model), tr->n * sizeof(float), "weights")) ||
        (s = sooc_dist_bcast(tr->m, tr->n * sizeof(float), "Adam m")) ||
        (s = sooc_dist_bcast(tr->v, tr->n * sizeof(float), "Adam v")))
        return s;
    tr->adam.adam_t = tr->st.adam_t;
    return SOOC_OK;
}

static void trainer_free(trainer *tr) {
    sooc_model_ws_destroy(tr->ws);
    sooc_model_destroy(tr->model);
    sooc_free(tr->m);
    sooc_free(tr->v);
    sooc_free(tr->gacc);
    sooc_free(tr->idbits);
}

sooc_status sooc_train_run(const sooc_train_config *cfg, const sooc_model_config *mc,
                           const sooc_train_run_params *rp) {
    trainer tr;
    memset(&tr, 0, sizeof tr);
    tr.cfg = cfg;
    tr.rp = rp;
    tr.rank = sooc_dist_rank();
    tr.size = sooc_dist_size();
    sooc_status s = sooc_mkdirs(rp->out_dir);
    if (s) return s;
    sooc_path_join(tr.path_last, sizeof tr.path_last, rp->out_dir, "last.bin");
    sooc_path_join(tr.path_best, sizeof tr.path_best, rp->out_dir, "best.bin");
    sooc_path_join(tr.path_log, sizeof tr.path_log, rp->out_dir, "log.csv");
    sooc_path_join(tr.path_val, sizeof tr.path_val, rp->out_dir, "val.csv");
    sooc_path_join(tr.path_png, sizeof tr.path_png, rp->out_dir, "curves.png");

    void *blob = NULL;
    size_t blob_n = 0;
    if (rp->resume && sooc_file_exists(tr.path_last)) {
        s = sooc_model_load(&tr.model, tr.path_last, &blob, &blob_n);
        if (s) return s;
        if (memcmp(sooc_model_get_config(tr.model), mc, sizeof *mc) != 0)
            sooc_log(SOOC_LOG_WARN, "%s: the checkpoint's model config differs from the config file; "
                                    "continuing with the checkpoint's", tr.path_last);
    } else {
        if (!rp->resume && sooc_file_exists(tr.path_last))
            return sooc_seterr(SOOC_EINVAL, "%s exists: pass --resume to continue it, or use another --out",
                               tr.path_last);
        s = sooc_model_create(&tr.model, mc, cfg->init_seed);
        if (s) return s;
        if (rp->init_path && (s = init_from(tr.model, mc, rp->init_path))) {
            sooc_model_destroy(tr.model);
            return s;
        }
    }
    sooc_model_set_threads(tr.model, cfg->threads);
    tr.n = sooc_model_param_count(tr.model);
    tr.m = sooc_calloc(tr.n, sizeof(float));
    tr.v = sooc_calloc(tr.n, sizeof(float));
    tr.idbits = sooc_malloc(65536 / 8);
    if (cfg->accum > 1) tr.gacc = sooc_malloc(tr.n * sizeof(float));
    if (!tr.m || !tr.v || !tr.idbits || (cfg->accum > 1 && !tr.gacc)) { s = SOOC_ENOMEM; goto done; }
    if ((s = sooc_model_ws_create(&tr.ws, tr.model))) goto done;
    tr.st.magic = TRAINER_MAGIC;
    tr.st.version = TRAINER_VERSION;
    tr.st.n_params = tr.n;
    tr.st.seed = cfg->seed;
    tr.st.best_val = -1;
    tr.st.best_step = -1;
    if (blob) {
        s = restore_blob(&tr, blob, blob_n);
        sooc_free(blob);
        blob = NULL;
        if (s) goto done;
        sooc_log(SOOC_LOG_INFO, "resuming %s at step %lld (best val mIoU %.4f at step %lld)", tr.path_last,
                 (long long)tr.st.step, tr.st.best_val, (long long)tr.st.best_step);
    }
    if (tr.rank == 0) {
        if ((s = trim_log(tr.path_log, tr.st.step)) || (s = trim_log(tr.path_val, tr.st.step))) goto done;
        if ((s = copy_config(rp->config_path, rp->out_dir))) goto done;
    }

    /* Adam over the model's flat slab: one view that covers everything. */
    sooc_nn_params_init(&tr.adam);
    snprintf(tr.view.name, sizeof tr.view.name, "model");
    tr.view.ndim = 1;
    tr.view.shape[0] = (int64_t)tr.n;
    tr.view.offset = 0;
    tr.view.n = tr.n;
    tr.view.lr_mult = 1;
    tr.view.wd_mult = 1;
    tr.adam.views = &tr.view;
    tr.adam.n_views = 1;
    tr.adam.n_total = tr.n;
    tr.adam.w = sooc_model_params(tr.model);
    tr.adam.g = sooc_model_grads(tr.model);
    tr.adam.m = tr.m;
    tr.adam.v = tr.v;
    tr.adam.adam_t = tr.st.adam_t;
    sooc_nn_adam_cfg acfg = sooc_nn_adam_default();
    sooc_nn_schedule sched = {cfg->lr, cfg->warmup, cfg->steps, cfg->lr_final_frac,
                              cfg->cosine ? SOOC_NN_DECAY_COSINE : SOOC_NN_DECAY_LINEAR};

    /* every rank starts from rank 0's weights, Adam moments and step */
    if (tr.size > 1 && (s = sync_ranks(&tr))) goto done;

    const sooc_dataset *ds = rp->train;
    sooc_frame views[64], queries[16];
    sooc_progress prog;
    int lead = tr.rank == 0;   /* rank 0 alone writes logs, validation, checkpoints, curves */
    /* progress (rate, ETA) counts the steps of this session, so a resumed run's
     * rate is not inflated by the steps done before; the absolute step is in `extra` */
    int64_t step0 = tr.st.step;
    if (rp->progress && lead)
        sooc_progress_begin(&prog, "train", (uint64_t)(cfg->steps > step0 ? cfg->steps - step0 : 0));
    double t_start = sooc_seconds();
    /* the per-stage columns (t_*) come after the original ones, so readers by
     * position keep working (docs/training.md "Where a step's time goes") */
    const char *hdr = "step,lr,tau,beta_kl,total,nll_input,kl,nll_query,nll_depth,nll_color,"
                      "present_slots,gt_visible,mean_pres_logit,map_entries,grad_norm,T,Q,sec_per_step,"
                      "t_data,t_forward,t_backward,t_optim,t_allreduce,t_val,t_ckpt,ranks\n";
    double acc[8] = {0};
    int acc_n = 0;
    char extra[256] = "";
    /* The curriculum (T input views, Q queries) is drawn once per step, from
     * the stream (seed, step), so every scene of a step, on every rank, has
     * the same T: no rank waits for another's longer segment. Scene j of the
     * step's batch (j = rank * accum + a, over all ranks) then draws its scene,
     * views and model noise from its own stream: for j = 0 the same (seed,
     * step) stream after the curriculum draw, as a single process always did
     * (accum 1 runs are unchanged), and (seed, step + j * 2^40) for j > 0.
     * So the data order is a function of (seed, step, ranks x accum) alone: N
     * ranks with accum a see the scenes one process sees with accum N a, and
     * --resume restores every rank's RNG by restoring the step. */
    const uint64_t batch = (uint64_t)tr.size * (uint64_t)cfg->accum;
    tr.st.batch = (uint32_t)batch;
    while (tr.st.step < cfg->steps) {
        int64_t step = tr.st.step;
        double ts = sooc_seconds();
        double t_data = 0, t_fwd = 0, t_bwd = 0, t_opt = 0, t_ar = 0, t0;
        sooc_step_opts o;
        sooc_step_opts_default(&o);
        o.tau = tau_at(cfg, step);
        o.beta_kl = cfg->kl_warmup > 0 ? fminf(1.0f, (float)(step + 1) / (float)cfg->kl_warmup) : 1.0f;
        o.pres_mode = step < cfg->burnin ? SOOC_PRES_ST_ONE
                      : cfg->st_retrieved ? SOOC_PRES_ST_RETRIEVED : SOOC_PRES_RELAXED;
        o.proposals = cfg->proposals;
        o.prop_join_m = cfg->prop_join_m;
        if (cfg->prop_logit != 0) o.prop_logit = cfg->prop_logit;
        sooc_model_zero_grad(tr.model);
        sooc_step_losses sum;
        memset(&sum, 0, sizeof sum);
        double vis = 0;
        int T = 1, Q = 1, ok_scenes = 0, nonfinite = 0;
        float *g = sooc_model_grads(tr.model);
        sooc_rng rng0;
        sooc_rng_seed(&rng0, cfg->seed, (uint64_t)step);
        curriculum(cfg, step, &rng0, &T, &Q);
        if (T > 64) T = 64;
        if (Q > 16) Q = 16;
        for (int a = 0; a < cfg->accum; a++) {
            t0 = sooc_seconds();
            /* accum > 1: every scene's gradient alone, then summed into gacc, so
             * that N ranks x accum a round like one process x accum N a (the
             * sums differ only in their order, not in how each scene rounds) */
            if (a > 0) sooc_model_zero_grad(tr.model);
            uint64_t j = (uint64_t)tr.rank * (uint64_t)cfg->accum + (uint64_t)a;
            sooc_rng rng = rng0;
            if (j > 0) sooc_rng_seed(&rng, cfg->seed, (uint64_t)step + (j << 40));
            int sc = sooc_dataset_pick(ds, cfg->recorded_frac, &rng), nv = 0, nq = 0;
            sooc_dataset_sample(ds, sc, T, Q, cfg->query_held_out, &rng, views, &nv, queries, &nq);
            double t1 = sooc_seconds();
            t_data += t1 - t0;
            sooc_step_losses l;
            if (sooc_model_is_global(tr.model))   /* MulMON-style baseline (docs/baseline.md) */
                s = sooc_model_global_train_step(tr.ws, views, nv, queries, nq, sooc_dataset_n_objects(ds, sc),
                                                 &o, &rng, &l);
            else
                s = sooc_model_train_step(tr.ws, views, nv, queries, nq, &o, &rng, &l);
            if (s) {
                sooc_adderr(s, "step %lld, scene %s", (long long)step, sooc_dataset_scene_path(ds, sc));
                goto done;
            }
            double t2 = sooc_seconds();
            t_bwd += l.sec_backward;
            t_fwd += (t2 - t1) - l.sec_backward;
            if (l.nonfinite) { nonfinite = 1; continue; }
            if (tr.gacc) {
                if (ok_scenes == 0) memcpy(tr.gacc, g, tr.n * sizeof(float));
                else for (size_t i = 0; i < tr.n; i++) tr.gacc[i] += g[i];
            }
            ok_scenes++;
            sum.total += l.total;
            sum.nll_input += l.nll_input;
            sum.kl += l.kl;
            sum.nll_query += l.nll_query;
            sum.nll_depth += l.nll_depth;
            sum.nll_color += l.nll_color;
            sum.present_slots += l.present_slots;
            sum.mean_pres_logit += l.mean_pres_logit;
            sum.map_entries += l.map_entries;
            vis += visible_objects(&tr, views, nv);
            t_data += sooc_seconds() - t2;
        }
        if (tr.gacc) {
            if (ok_scenes > 0) memcpy(g, tr.gacc, tr.n * sizeof(float));
            else sooc_model_zero_grad(tr.model);
        }
        /* the stop decision is taken together, so that no rank leaves the others waiting */
        int stop = (rp->stop_flag && *rp->stop_flag) ||
                   (cfg->val_max_seconds > 0 && sooc_seconds() - t_start > cfg->val_max_seconds);
        if (tr.size > 1) {
            t0 = sooc_seconds();
            double red[13] = {ok_scenes, nonfinite, stop, sum.total, sum.nll_input, sum.kl, sum.nll_query,
                              sum.nll_depth, sum.nll_color, sum.present_slots, sum.mean_pres_logit,
                              sum.map_entries, vis};
            /* one in-place allreduce over the flat gradient slab (a rank whose
             * scenes were all non-finite adds zeros), one for the loss sums */
            if ((s = sooc_dist_sum_f64(red, 13, "loss sums")) ||
                (s = sooc_dist_sum_f32(sooc_model_grads(tr.model), tr.n, "gradient slab")))
                goto done;
            ok_scenes = (int)red[0], nonfinite = red[1] > 0, stop = red[2] > 0;
            sum.total = red[3], sum.nll_input = red[4], sum.kl = red[5], sum.nll_query = red[6];
            sum.nll_depth = red[7], sum.nll_color = red[8], sum.present_slots = red[9];
            sum.mean_pres_logit = red[10], sum.map_entries = red[11], vis = red[12];
            t_ar = sooc_seconds() - t0;
        }
        t0 = sooc_seconds();
        double gnorm = NAN;
        float lr = sooc_nn_schedule_lr(&sched, step);
        if (ok_scenes > 0) {
            if (ok_scenes > 1) {
                float sc = 1.0f / (float)ok_scenes;
                for (size_t i = 0; i < tr.n; i++) g[i] *= sc;
            }
            gnorm = sooc_nn_clip_grad_norm(&tr.adam, cfg->clip);
            s = isfinite(gnorm) ? sooc_nn_adam_step(&tr.adam, &acfg, lr) : SOOC_ENUMERIC;
            if (s == SOOC_ENUMERIC) { s = SOOC_OK; nonfinite = 1; }
            else if (s) goto done;
        }
        t_opt = sooc_seconds() - t0;
        if (nonfinite) tr.st.skipped++;
        tr.st.step = step + 1;
        double inv = ok_scenes ? 1.0 / ok_scenes : NAN;
        double row[8] = {sum.total * inv, sum.nll_input * inv, sum.kl * inv, sum.nll_query * inv,
                         sum.present_slots * inv, vis * inv, sum.mean_pres_logit * inv, gnorm};
        for (int i = 0; i < 8; i++) acc[i] += row[i];
        acc_n++;
        if (lead && (tr.st.step % cfg->log_every == 0 || tr.st.step == cfg->steps)) {
            char line[768];
            snprintf(line, sizeof line,
                     "%lld,%.4g,%.4f,%.4f,%.6g,%.6g,%.6g,%.6g,%.6g,%.6g,%.3f,%.3f,%.4f,%.2f,%.4g,%d,%d,%.3f,"
                     "%.6f,%.6f,%.6f,%.6f,%.6f,%.3f,%.3f,%d\n",
                     (long long)step, lr, o.tau, o.beta_kl, row[0], row[1], row[2], row[3],
                     sum.nll_depth * inv, sum.nll_color * inv, row[4], row[5], row[6], sum.map_entries * inv,
                     gnorm, T, Q, sooc_seconds() - ts, t_data, t_fwd, t_bwd, t_opt, t_ar, tr.t_val, tr.t_ckpt,
                     tr.size);
            tr.t_val = tr.t_ckpt = 0;
            if ((s = append_line(tr.path_log, hdr, line))) goto done;
            snprintf(extra, sizeof extra, "step %lld loss %.4g nll %.4g kl %.4g query %.4g slots %.2f/%.2f gt lr %.2e tau %.2f%s",
                     (long long)tr.st.step, acc[0] / acc_n, acc[1] / acc_n, acc[2] / acc_n, acc[3] / acc_n, acc[4] / acc_n,
                     acc[5] / acc_n, lr, o.tau, tr.st.skipped ? " (skips)" : "");
            memset(acc, 0, sizeof acc);
            acc_n = 0;
        }
        if (rp->progress && lead) sooc_progress_update(&prog, (uint64_t)(tr.st.step - step0), extra);
        if (rp->step_hook) rp->step_hook(rp->hook_user, tr.st.step);
        if (lead && cfg->val_every > 0 && (tr.st.step % cfg->val_every == 0 || tr.st.step == cfg->steps)) {
            t0 = sooc_seconds();
            if ((s = run_validation(&tr, tr.st.step))) goto done;
            tr.t_val += sooc_seconds() - t0;
        }
        if (lead && (tr.st.step % cfg->ckpt_every == 0 || tr.st.step == cfg->steps || stop)) {
            t0 = sooc_seconds();
            if ((s = save_ckpt(&tr, tr.path_last))) goto done;
            sooc_status ps = sooc_eval_plot_csv(tr.path_log, tr.path_png, "sooc3d training");
            if (ps) sooc_log(SOOC_LOG_WARN, "curves: %s", sooc_errmsg());
            tr.t_ckpt += sooc_seconds() - t0;
        }
        if (stop) {
            if (lead) sooc_log(SOOC_LOG_INFO, "stopping at step %lld (checkpoint %s)", (long long)tr.st.step, tr.path_last);
            break;
        }
    }
    if (rp->progress && lead) {
        /* stopped early (signal, --max-seconds): the last line shows the steps done, not 100% */
        if (tr.st.step < cfg->steps) prog.total = (uint64_t)(tr.st.step - step0);
        sooc_progress_end(&prog, extra);
    }
done:
    sooc_free(blob);
    trainer_free(&tr);
    return s;
}
