/* bench_finetune: wall time of `sooc3d finetune` with the default
 * iterations on a medium unity scene (bar: <= 60 s on this machine's 2 cores),
 * and the cost per object against the map's size (a large scene's map holds
 * ~9x the objects: the per-unit time must not grow with it).
 *
 * Each scene: sooc_gen_scene (seed 9001, held out), its input views rendered
 * at the model's resolution, online inference with the shipped model, then
 * births (the default, docs/finetune.md "Births and deaths"), sooc_finetune_run
 * over every unit (objects, then layout blocks), then deaths. `seconds` is the
 * finetuning (build + all units); births and deaths are timed apart, and
 * `total` is all three; inference is not part of it.
 *
 *   bench_finetune [--model M] [--scenes N] [--iterations K] [--no-large] [--no-birth]
 * Prints a line per scene and a JSON object last. */
#include "sooc3d/train.h"
#include "sooc3d/gen.h"
#include "sooc3d/model.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifndef SOOC_SOURCE_DIR
#define SOOC_SOURCE_DIR "."
#endif

typedef struct scene_run {
    int n_views, n_entries, n_units, n_objects_units;
    double seconds, s_per_unit, s_per_object, ms_per_step;
    double ll_before, ll_after;   /* mean ℓ per ray, fixed samples */
    int born, removed;
    double birth_s, death_s;
} scene_run;

static sooc_status run_scene(const char *model, sooc_gen_scale scale, int index, const sooc_finetune_params *fp,
                             int birth, scene_run *out) {
    memset(out, 0, sizeof *out);
    sooc_model *m = NULL;
    sooc_mapper *mp = NULL;
    sooc_finetune *ft = NULL;
    sooc_scene sc;
    sooc_scene_init(&sc);
    sooc_frame *fr = NULL;
    int nfr = 0;
    sooc_status st = sooc_model_load(&m, model, NULL, NULL);
    if (st) return st;
    const sooc_model_config *c = sooc_model_get_config(m);
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY, gp.scale = scale, gp.seed = 9001;
    gp.width = c->img_w, gp.height = c->img_h;
    if ((st = sooc_gen_scene(&sc, &gp, index))) goto done;
    fr = calloc((size_t)sc.n_views, sizeof *fr);
    if (!fr) {
        st = SOOC_ENOMEM;
        goto done;
    }
    sooc_intrinsics K;
    sooc_gen_intrinsics(&K, gp.width, gp.height, sc.fov_deg);
    if ((st = sooc_mapper_create_with_model(&mp, m, 0, 1, 0))) goto done;
    m = NULL;   /* owned by the mapper */
    sooc_model *mm = sooc_mapper_model(mp);
    for (int v = 0; v < sc.n_views; v++) {
        if (sc.view_is_query[v]) continue;
        sooc_frame *f = &fr[nfr];
        if ((st = sooc_gen_render_view(&sc, sc.view_T_wc + 16 * v, &K, f))) goto done;
        f->has_pose = 1, f->index = v;
        nfr++;
        sooc_update_stats us;
        if ((st = sooc_mapper_update(mp, f, &us))) goto done;
    }
    sooc_cogmap *map = (sooc_cogmap *)sooc_mapper_cogmap(mp);
    if (birth) {
        double tb = sooc_seconds();
        sooc_birth *b = NULL;
        if ((st = sooc_birth_create(&b, mm, map, NULL, 0))) goto done;
        for (int i = 0; i < nfr && !st; i++) st = sooc_birth_add_view(b, &fr[i]);
        if (!st) st = sooc_birth_run(b, NULL, 0, &out->born);
        sooc_birth_destroy(b);
        if (st) goto done;
        out->birth_s = sooc_seconds() - tb;
    }
    double t0 = sooc_seconds();
    if ((st = sooc_finetune_create(&ft, mm, map, fp))) goto done;
    for (int i = 0; i < nfr; i++)
        if ((st = sooc_finetune_add_view(ft, &fr[i]))) goto done;
    size_t nr = 0;
    double ll = 0;
    if ((st = sooc_finetune_loglik(ft, 77, &ll, &nr))) goto done;
    double tl = sooc_seconds() - t0;   /* not part of a run: subtracted below */
    out->ll_before = nr ? ll / (double)nr : 0;
    int nu = sooc_finetune_n_units(ft);
    double t_obj = 0;
    for (int u = 0; u < nu; u++) {
        sooc_finetune_unit un;
        sooc_finetune_result r;
        if ((st = sooc_finetune_unit_get(ft, u, &un)) || (st = sooc_finetune_unit_run(ft, u, NULL, NULL, 0, &r)))
            goto done;
        if (un.kind == SOOC_FT_OBJECT) t_obj += r.seconds, out->n_objects_units++;
    }
    out->seconds = sooc_seconds() - t0 - tl;
    if ((st = sooc_finetune_loglik(ft, 77, &ll, &nr))) goto done;
    out->ll_after = nr ? ll / (double)nr : 0;
    if (birth) {
        double td = sooc_seconds();
        if ((st = sooc_birth_prune_all(mm, map, NULL, &out->removed))) goto done;
        out->death_s = sooc_seconds() - td;
    }
    out->n_views = nfr, out->n_units = nu, out->n_entries = (int)sooc_cogmap_count(map);
    out->s_per_unit = nu ? out->seconds / nu : 0;
    out->s_per_object = out->n_objects_units ? t_obj / out->n_objects_units : 0;
    out->ms_per_step = nu && fp->iterations ? 1e3 * out->seconds / ((double)nu * fp->iterations) : 0;
done:
    sooc_finetune_destroy(ft);
    sooc_mapper_destroy(mp);
    sooc_model_destroy(m);
    for (int i = 0; i < nfr; i++) sooc_frame_free(&fr[i]);
    free(fr);
    sooc_scene_free(&sc);
    return st;
}

int main(int argc, char **argv) {
    const char *model = SOOC_SOURCE_DIR "/models/sooc3d_unity/model.bin";
    int scenes = 1, large = 1, birth = 1;
    sooc_finetune_params fp;
    sooc_finetune_params_default(&fp);
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(argv[i], "--scenes") && i + 1 < argc) scenes = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--iterations") && i + 1 < argc) fp.iterations = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--no-large")) large = 0;
        else if (!strcmp(argv[i], "--no-birth")) birth = 0;
        else {
            fprintf(stderr, "usage: bench_finetune [--model M] [--scenes N] [--iterations K] [--no-large] [--no-birth]\n");
            return 2;
        }
    }
    if (scenes < 1) scenes = 1;
    double sec_max = 0, sec_sum = 0, spo_m = 0, ms_step_m = 0, dll = 0, tot_max = 0, tot_sum = 0, bs = 0, ds = 0;
    int units_m = 0, ent_m = 0, born_m = 0, rem_m = 0;
    for (int s = 0; s < scenes; s++) {
        scene_run r;
        sooc_status st = run_scene(model, SOOC_GEN_M, s, &fp, birth, &r);
        if (st) {
            fprintf(stderr, "bench_finetune: %s: %s\n", sooc_status_str(st), sooc_errmsg());
            return 1;
        }
        printf("m scene %d: %d views, %d entries, %d units: %.2f s (%.3f s/unit, %.3f s/object, %.2f ms/step), "
               "mean ll/ray %.4f -> %.4f; births %d in %.2f s, deaths %d in %.2f s\n",
               s, r.n_views, r.n_entries, r.n_units, r.seconds, r.s_per_unit, r.s_per_object, r.ms_per_step,
               r.ll_before, r.ll_after, r.born, r.birth_s, r.removed, r.death_s);
        double tot = r.birth_s + r.seconds + r.death_s;
        if (tot > tot_max) tot_max = tot;
        tot_sum += tot, bs += r.birth_s, ds += r.death_s, born_m += r.born, rem_m += r.removed;
        if (r.seconds > sec_max) sec_max = r.seconds;
        sec_sum += r.seconds, spo_m += r.s_per_object, ms_step_m += r.ms_per_step, dll += r.ll_after - r.ll_before;
        units_m += r.n_units, ent_m += r.n_entries;
    }
    scene_run rl;
    memset(&rl, 0, sizeof rl);
    if (large) {
        sooc_status st = run_scene(model, SOOC_GEN_L, 0, &fp, birth, &rl);
        if (st) {
            fprintf(stderr, "bench_finetune: %s: %s\n", sooc_status_str(st), sooc_errmsg());
            return 1;
        }
        printf("l scene 0: %d views, %d entries, %d units: %.2f s (%.3f s/unit, %.3f s/object, %.2f ms/step)\n",
               rl.n_views, rl.n_entries, rl.n_units, rl.seconds, rl.s_per_unit, rl.s_per_object, rl.ms_per_step);
    }
    double spo = spo_m / scenes;
    printf("{\"bench\": \"finetune\", \"iterations\": %d, \"rays\": %d, \"m_scenes\": %d, \"m_seconds_mean\": %.3f, "
           "\"m_seconds_max\": %.3f, \"bar_seconds\": 60, \"m_units_mean\": %.1f, \"m_entries_mean\": %.1f, "
           "\"m_s_per_object\": %.4f, \"m_ms_per_step\": %.3f, \"m_dll_per_ray\": %.4f, \"l_entries\": %d, "
           "\"l_units\": %d, \"l_seconds\": %.3f, \"l_s_per_object\": %.4f, \"per_object_ratio_l_over_m\": %.3f, "
           "\"births\": %s, \"m_born_mean\": %.1f, \"m_removed_mean\": %.1f, \"m_birth_seconds_mean\": %.3f, "
           "\"m_death_seconds_mean\": %.3f, \"m_total_seconds_mean\": %.3f, \"m_total_seconds_max\": %.3f}\n",
           fp.iterations, fp.rays, scenes, sec_sum / scenes, sec_max, (double)units_m / scenes,
           (double)ent_m / scenes, spo, ms_step_m / scenes, dll / scenes, rl.n_entries, rl.n_units, rl.seconds,
           rl.s_per_object, large && spo > 0 ? rl.s_per_object / spo : 0.0, birth ? "true" : "false",
           (double)born_m / scenes, (double)rem_m / scenes, bs / scenes, ds / scenes, tot_sum / scenes, tot_max);
    return 0;
}
