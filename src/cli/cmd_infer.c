/* sooc3d infer: run the online mapper over a sequence, write the final map
 * (JSON + CSV) and per-view renders from the final map. */
#include "cli.h"
#include "sooc3d/frame.h"
#include "sooc3d/core.h"
#include "sooc3d/mapper.h"
#include "sooc3d/model.h"
#include "sooc3d/render.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void usage(FILE *f) {
    fprintf(f,
            "usage: sooc3d infer --model M --seq DIR --out DIR [--iterations L] [--seed S] [--threads T]\n"
            "                    [--every K] [--max-frames N] [--no-render] [--samples N] [--clip D]\n"
            "                    [--merge R] [--revisit] [--latents mean|sample] [--slots N] [--trace]\n"
            "                    [--calib F] [--format NAME] [--depth-scale S] [--depth-shift N]\n"
            "                    [--min-depth M] [--max-depth M] [--up X,Y,Z] [--world W]\n\n"
            "Runs the online amortised variational update (query -> pad -> refine L times ->\n"
            "register) once per input frame of the sequence and writes\n"
            "  DIR/map.json, DIR/map.csv    the final cognitive map (world frame, ordered by id; map.json\n"
            "                               also holds the world frame: T_world_src and its source)\n"
            "  DIR/updates.csv              per-update stats (retrieved, registered, new, removed, merged, ms,\n"
            "                               same_pose, retired, gated: docs/cogmap.md \"Revisits\")\n"
            "  DIR/trace.csv                with --trace: every map change of every update (frame,\n"
            "                               event reg|del, id, x, z, yaw, presence, obs_count)\n"
            "  DIR/render/%%06d_{rgb,depth,label}.png  renders of every frame from the final map\n"
            "                               (input and query views; 96 coarse + 32 fine samples)\n\n"
            "  --model       model checkpoint (models/<name>/model.bin)\n"
            "  --seq         sequence directory (any format sooc3d reads, any resolution); frames without\n"
            "                a pose and query frames (scene.yaml) are not mapped\n"
            "  --iterations  refinement updates per frame (default: the model's L)\n"
            "  --seed        seed of the ray offsets (and posterior samples with --latents sample);\n"
            "                results are deterministic for a seed (default 1)\n"
            "  --every       map every K-th input frame (default 1)\n"
            "  --max-frames  stop after N frames (default all)\n"
            "  --samples     render samples per ray, coarse (default 96)\n"
            "  --clip        clip depth in m instead of the model's (e.g. the sensor's usable range)\n"
            "  --merge       duplicate radius R m: entries one frame registers closer than R are\n"
            "                merged, a new entry that close to an older one is dropped; 0 = never\n"
            "                (default: the paper registers without object matching); 0.35 measured\n"
            "                best (docs/cogmap.md)\n"
            "  --revisit     with --merge: the node's revisit rules (hold entries that left the view,\n"
            "                settled entries average, merge neighbours, retire entries the depth shows\n"
            "                as free, the creation gate; docs/cogmap.md \"Revisits\")\n"
            "  --latents     refine on the posterior means (mean, default) or on one posterior sample\n"
            "                per iteration as in training (sample); docs/model.md\n"
            "  --slots       object slots per frame; 0 = the model's setting (default: its config slots,\n"
            "                else its trained K; the shipped model: 10). More than K pads the extra\n"
            "                slots with mirrored learnt priors (docs/model.md, slots at inference)\n"
            "  --trace       write DIR/trace.csv\n\n"
            "%s",
            sooc_cli_framepath_help);
}

static sooc_status write_map(const char *dir, const sooc_map_entry *e, size_t n, const sooc_framepath *fp) {
    char path[1024];
    sooc_status st = sooc_path_join(path, sizeof path, dir, "map.json");
    if (st) return st;
    size_t cap = 4096 + n * 2048, len = 0;
    char *b = malloc(cap);
    if (!b) return SOOC_ENOMEM;
    double T[16];
    sooc_framepath_world w = sooc_framepath_world_get(fp, T);
    len += (size_t)snprintf(b + len, cap - len, "{\n  \"world\": {\"source\": \"%s\", \"T_world_src\": [",
                            sooc_framepath_world_name(w));
    for (int k = 0; k < 16; k++) len += (size_t)snprintf(b + len, cap - len, "%s%.9g", k ? ", " : "", T[k]);
    len += (size_t)snprintf(b + len, cap - len, "]},\n  \"entries\": [\n");
    for (size_t i = 0; i < n; i++) {
        double st, syaw;   /* the planner's sigmas, as the table and `map export` give them */
        sooc_map_entry_planner_sigmas(&e[i], &st, &syaw);
        char sy[32] = "null";   /* a symmetric object's yaw has no spread */
        if (isfinite(syaw)) snprintf(sy, sizeof sy, "%.6f", syaw);
        len += (size_t)snprintf(b + len, cap - len,
                                "    {\"id\": %llu, \"x\": %.6f, \"z\": %.6f, \"yaw\": %.6f, \"sigma_t\": %.6f, "
                                "\"sigma_yaw\": %s, \"presence\": %.6f, \"presence_logit\": %.6f, "
                                "\"extent\": [%.3f, %.3f, %.3f], \"obs_count\": %u, \"first_seen_ns\": %lld, "
                                "\"last_seen_ns\": %lld, \"what_mu\": [",
                                (unsigned long long)e[i].id, e[i].x, e[i].z, e[i].yaw, st, sy,
                                e[i].presence, e[i].presence_logit, e[i].extent[0], e[i].extent[1], e[i].extent[2],
                                e[i].obs_count, (long long)e[i].first_seen_ns, (long long)e[i].last_seen_ns);
        for (int k = 0; k < e[i].latent_dim; k++)
            len += (size_t)snprintf(b + len, cap - len, "%s%.6g", k ? ", " : "", e[i].what_mu[k]);
        len += (size_t)snprintf(b + len, cap - len, "], \"what_logvar\": [");
        for (int k = 0; k < e[i].latent_dim; k++)
            len += (size_t)snprintf(b + len, cap - len, "%s%.6g", k ? ", " : "", e[i].what_logvar[k]);
        len += (size_t)snprintf(b + len, cap - len, "]}%s\n", i + 1 < n ? "," : "");
    }
    len += (size_t)snprintf(b + len, cap - len, "  ]\n}\n");
    st = sooc_file_write_atomic(path, b, len);
    if (!st) {
        len = 0;
        len += (size_t)snprintf(b + len, cap - len, "id,x,z,yaw,sigma_t,sigma_yaw,presence,obs_count\n");
        for (size_t i = 0; i < n; i++) {
            double st, syaw;
            sooc_map_entry_planner_sigmas(&e[i], &st, &syaw);
            len += (size_t)snprintf(b + len, cap - len, "%llu,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%u\n",
                                    (unsigned long long)e[i].id, e[i].x, e[i].z, e[i].yaw, st, syaw, e[i].presence,
                                    e[i].obs_count);
        }
        if (!(st = sooc_path_join(path, sizeof path, dir, "map.csv"))) st = sooc_file_write_atomic(path, b, len);
    }
    free(b);
    return st;
}

static sooc_status render_frame(sooc_mapper *mp, const sooc_frame *f, const char rdir[1024], int samples, int threads) {
    sooc_model_field *fld;
    sooc_status st = sooc_model_field_create(&fld, sooc_mapper_model(mp), sooc_mapper_cogmap(mp), f->T_wc, &f->K,
                                             63, NULL);
    if (st) return st;
    const sooc_model_config *c = sooc_model_get_config(sooc_mapper_model(mp));
    sooc_render_opts o;
    sooc_render_opts_default(&o);
    o.n_coarse = samples;
    o.t_near = c->t_near * c->unit_m, o.d_clip = c->d_clip * c->unit_m;   /* metres */
    o.threads = threads;
    double T_fc[16];
    sooc_model_field_T_fc(fld, T_fc);
    sooc_render_out ro;
    memset(&ro, 0, sizeof ro);
    st = sooc_render_view(sooc_model_field_get(fld), &f->K, T_fc, &o, &ro);
    if (!st) {
        int W = ro.width, H = ro.height;
        sooc_image img;
        memset(&img, 0, sizeof img);
        char path[1200];
        uint8_t *rgb = malloc((size_t)W * H * 3);
        uint16_t *ids = malloc((size_t)W * H * 2);
        for (int i = 0; i < W * H * 3; i++) {
            float v = ro.rgb[i] < 0 ? 0 : ro.rgb[i] > 1 ? 1 : ro.rgb[i];
            rgb[i] = (uint8_t)(255.0f * v + 0.5f);
        }
        for (int i = 0; i < W * H; i++) {
            int lab = ro.label[i];
            ids[i] = (uint16_t)(lab < 0 ? 0 : lab == 0 ? 0 : sooc_model_field_comp_id(fld, lab) & 0xffff);
        }
        snprintf(path, sizeof path, "%s/%06lld_rgb.png", rdir, (long long)f->index);
        if (!(st = sooc_image_from_rgb(&img, rgb, W, H))) st = sooc_png_write(path, &img, 6);
        snprintf(path, sizeof path, "%s/%06lld_depth.png", rdir, (long long)f->index);
        if (!st && !(st = sooc_image_from_depth(&img, ro.depth, W, H, 0.0, c->d_clip * c->unit_m))) st = sooc_png_write(path, &img, 6);
        snprintf(path, sizeof path, "%s/%06lld_label.png", rdir, (long long)f->index);
        if (!st && !(st = sooc_image_from_ids(&img, ids, W, H))) st = sooc_png_write(path, &img, 6);
        sooc_image_free(&img);
        free(rgb);
        free(ids);
    }
    sooc_render_out_free(&ro);
    sooc_model_field_destroy(fld);
    return st;
}

/* --trace: the entries the last update registered and the ids it removed.
 * Ids from `born` on were created by this update; one it merged away again
 * never was in the map, so it is not a removal here (updates.csv counts it). */
static sooc_status write_trace(FILE *tc, const sooc_mapper *mp, int64_t frame, uint64_t born) {
    sooc_map_entry ch[SOOC_MAPPER_CHANGED_MAX];
    uint64_t rm[SOOC_MAPPER_CHANGED_MAX];
    size_t nc = 0, nr = 0;
    sooc_status st = sooc_mapper_changed(mp, ch, SOOC_MAPPER_CHANGED_MAX, &nc, rm, SOOC_MAPPER_CHANGED_MAX, &nr);
    if (st) return st;
    for (size_t j = 0; j < nc; j++)
        fprintf(tc, "%lld,reg,%llu,%.4f,%.4f,%.4f,%.4f,%u\n", (long long)frame, (unsigned long long)ch[j].id, ch[j].x,
                ch[j].z, ch[j].yaw, ch[j].presence, ch[j].obs_count);
    for (size_t j = 0; j < nr; j++)
        if (rm[j] < born) fprintf(tc, "%lld,del,%llu,,,,,\n", (long long)frame, (unsigned long long)rm[j]);
    return SOOC_OK;
}

int sooc_cmd_infer(int argc, char **argv) {
    if (sooc_cli_wants_help(argc, argv)) {
        usage(stdout);
        return 0;
    }
    const char *model = NULL, *seq = NULL, *out = NULL;
    int iters = 0, threads = 0, every = 1, render = 1, samples = 96, trace = 0, latents = SOOC_LATENTS_MEAN;
    int slots = 0;
    double clip = 0, merge = 0;
    int revisit = 0;
    long long maxf = -1;
    uint64_t seed = 1;
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    int fo;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        int has = i + 1 < argc;
#define INTV(lo, hi, x) do { if (!sooc_cli_int_opt("infer", a, argv[++i], lo, hi, x)) return 2; } while (0)
        if (!strcmp(a, "--model") && has) model = argv[++i];
        else if (!strcmp(a, "--seq") && has) seq = argv[++i];
        else if (!strcmp(a, "--out") && has) out = argv[++i];
        else if (!strcmp(a, "--iterations") && has) INTV(0, 16, &iters);
        else if (!strcmp(a, "--clip") && has) {
            if (!sooc_cli_double_opt("infer", a, argv[++i], 0.01, 1000, &clip)) return 2;
        }
        else if (!strcmp(a, "--merge") && has) {
            if (!sooc_cli_parse_merge(argv[++i], &merge)) {
                fprintf(stderr, "sooc3d infer: --merge wants a radius >= 0 in metres (0 = never merge)\n");
                return 2;
            }
        }
        else if (!strcmp(a, "--revisit")) revisit = 1;
        else if (!strcmp(a, "--threads") && has) INTV(0, 256, &threads);
        else if (!strcmp(a, "--seed") && has) { if (!sooc_cli_u64_opt("infer", a, argv[++i], UINT64_MAX, &seed)) return 2; }
        else if (!strcmp(a, "--every") && has) INTV(1, 1000000, &every);
        else if (!strcmp(a, "--max-frames") && has) {
            if (!sooc_cli_count_opt("infer", a, argv[++i], &maxf)) return 2;
        }
        else if (!strcmp(a, "--samples") && has) INTV(2, 4064, &samples); /* + 32 fine <= the renderer's 4096 */
        else if (!strcmp(a, "--no-render")) render = 0;
        else if (!strcmp(a, "--trace")) trace = 1;
        else if (!strcmp(a, "--latents") && has) {
            if (!sooc_cli_parse_latents(argv[++i], &latents)) {
                fprintf(stderr, "sooc3d infer: --latents wants mean or sample\n");
                return 2;
            }
        }
        else if ((fo = sooc_cli_framepath_opt("infer", argc, argv, &i, &fpp)) != 0) {
            if (fo < 0) return 2;
        }
        else if (!strcmp(a, "--slots") && has) {
            if (!sooc_cli_parse_slots(argv[++i], &slots)) {
                fprintf(stderr, "sooc3d infer: --slots wants 0 (the model's) up to %d object slots\n", SOOC_MODEL_K_MAX);
                return 2;
            }
        }
        else {
            fprintf(stderr, "sooc3d infer: unknown or incomplete option '%s'\n", a);
            usage(stderr);
            return 2;
        }
#undef INTV
    }
    if (!model || !seq || !out) {
        usage(stderr);
        return 2;
    }
    if (!sooc_cli_framepath_check("infer", &fpp)) return 2;
    sooc_status st;
    sooc_framepath *sq = NULL;
    sooc_mapper *mp = NULL;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    FILE *uc = NULL, *tc = NULL;
    char path[1024], rdir[1024];
    if ((st = sooc_mkdirs(out))) return sooc_cli_fail("infer", st);
    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.model_path = model, p.iterations = iters, p.seed = seed, p.threads = threads, p.d_clip = clip;
    p.merge_radius = merge;
    p.merge_neighbours = revisit && merge > 0;   /* the node's revisit rules, creation gate included */
    p.latents = latents;
    p.slots = slots;
    if ((st = sooc_mapper_create(&mp, &p))) goto fail;
    sooc_cli_framepath_model(&fpp, sooc_model_get_config(sooc_mapper_model(mp)));
    if ((st = sooc_framepath_open(&sq, seq, &fpp))) goto fail;
    int64_t n = sooc_framepath_count(sq);
    if (maxf >= 0 && maxf < n) n = maxf;
    snprintf(path, sizeof path, "%s/updates.csv", out);
    uc = fopen(path, "w");
    if (!uc) {
        st = sooc_seterr(SOOC_EIO, "%s: cannot open for writing", path);
        goto fail;
    }
    fprintf(uc, "frame,t_ns,retrieved,registered,new,removed,merged,ms,same_pose,retired,gated\n");
    if (trace) {
        snprintf(path, sizeof path, "%s/trace.csv", out);
        if (!(tc = fopen(path, "w"))) {
            st = sooc_seterr(SOOC_EIO, "%s: cannot open for writing", path);
            goto fail;
        }
        fprintf(tc, "frame,event,id,x,z,yaw,presence,obs_count\n");
    }
    sooc_progress pr;
    sooc_progress_begin(&pr, "infer", (uint64_t)n);
    int64_t n_in = 0, mapped = 0;
    double ms_sum = 0;
    for (int64_t i = 0; i < n; i++) {
        if ((st = sooc_framepath_read(sq, i, &f))) goto fail;
        if (f.is_query || !f.has_pose) continue;
        if (n_in++ % every) continue;
        sooc_update_stats us;
        uint64_t born = sooc_mapper_next_id(mp);
        if ((st = sooc_mapper_update(mp, &f, &us))) goto fail;
        mapped++;
        ms_sum += us.elapsed_ms;
        fprintf(uc, "%lld,%lld,%d,%d,%d,%d,%d,%.3f,%d,%d,%d\n", (long long)i, (long long)f.t_ns, us.n_retrieved,
                us.n_registered, us.n_new, us.n_removed, us.n_merged, us.elapsed_ms, us.n_same_pose, us.n_retired,
                us.n_gated);
        if (tc && (st = write_trace(tc, mp, i, born))) goto fail;
        char extra[96];
        size_t ne = 0;
        sooc_mapper_entries(mp, NULL, 0, &ne);
        snprintf(extra, sizeof extra, "map %zu, %.1f ms/update", ne, ms_sum / (double)mapped);
        sooc_progress_update(&pr, (uint64_t)i + 1, extra);
    }
    sooc_progress_end(&pr, NULL);
    fclose(uc);
    uc = NULL;
    if (tc && fclose(tc)) {
        tc = NULL;
        st = sooc_seterr(SOOC_EIO, "%s/trace.csv: write failed", out);
        goto fail;
    }
    tc = NULL;
    size_t ne = 0;
    sooc_mapper_entries(mp, NULL, 0, &ne);
    sooc_map_entry *e = calloc(ne ? ne : 1, sizeof *e);
    if (!e) {
        st = SOOC_ENOMEM;
        goto fail;
    }
    if (!(st = sooc_mapper_entries(mp, e, ne, &ne))) st = write_map(out, e, ne, sq);
    free(e);
    if (st) goto fail;
    printf("infer: %lld frames mapped (%.1f ms/update mean), %zu map entries -> %s/map.json\n", (long long)mapped,
           mapped ? ms_sum / (double)mapped : 0.0, ne, out);
    if (sooc_framepath_empty_depth(sq) > 0)
        fprintf(stderr, "sooc3d infer: warning: %lld frames had no valid depth in [%g, %g] m after preprocessing "
                        "(check the depth scale: --calib, --depth-scale, --depth-shift)\n",
                (long long)sooc_framepath_empty_depth(sq), fpp.min_depth_m, fpp.max_depth_m);
    if (render) {
        snprintf(rdir, sizeof rdir, "%s/render", out);
        if ((st = sooc_mkdirs(rdir))) goto fail;
        int nr = 0;
        for (int64_t i = 0; i < n; i++) {
            if ((st = sooc_framepath_read(sq, i, &f))) goto fail;
            if (!f.has_pose) continue;
            if ((st = render_frame(mp, &f, rdir, samples, threads))) goto fail;
            nr++;
        }
        printf("infer: %d views rendered from the final map -> %s\n", nr, rdir);
    }
    sooc_frame_free(&f);
    sooc_mapper_destroy(mp);
    sooc_framepath_close(sq);
    return 0;
fail:
    if (uc) fclose(uc);
    if (tc) fclose(tc);
    sooc_frame_free(&f);
    sooc_mapper_destroy(mp);
    sooc_framepath_close(sq);
    return sooc_cli_fail("infer", st);
}
