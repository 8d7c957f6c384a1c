/* Soak: one generated unity scene replayed in a loop through the node with
 * the shipped model (`replay loop: true`, block_when_full) for N keyframes
 * (default 10,000), a persistent map.db and the node's default settings
 * (model.merge_m). A monitor thread samples the node's stats: the map size
 * after the first pass over the scene, at the end and its maximum, resident
 * memory (VmRSS) and open file descriptors after the first pass, after 10% of
 * the keyframes and at the end, and the map size at every 1,000th keyframe
 * (entries_per_1000: the count moves as duplicates appear and are merged or
 * retired, so one end value says little). The generated scene gives ground
 * truth: a separate one-pass run into its own map.db and the looped map are
 * both scored (gt_*: each entry against the nearest object centre on the
 * floor; within 0.6 m it maps that object, the first such entry counts and
 * later ones are duplicates, farther ones are "far": a wall or a ghost), and
 * the median of the entries' distances to their objects (drift). Prints a
 * JSON object as its last line.
 *
 * --seq PATH loops a recorded sequence instead (any replay format, e.g.
 * ../shared/real/7scenes_redkitchen) with its own poses and the support plane
 * estimated (world.floor: estimate); the reference pass runs to the end of
 * the sequence once, and its keyframe count is the pass length. No ground
 * truth (gt_* are null; "scale": "real").
 *
 *   bench_soak [--keyframes N] [--scale s|m|l] [--seed S] [--seq PATH] [--slots K] [--merge R] [--clip M] [--model PATH]
 *              [--out DIR] [--gate-min F] [--gate-ratio F] [--gate-part F] [--log debug|info|warn]
 *
 * --list [--long] [--total N]: the fixed list of scenes (soak_list below: eight
 * generated scenes of the three scales and 7-Scenes redkitchen when
 * ../shared/real holds it), N keyframes in all shared evenly between them
 * (10,000; --long 100,000), each scene in a child process of this program
 * with the options above. The last line is one JSON object: every scene's
 * run, how many stay within 10% of their first pass, the keyframe rate and
 * the time the long mode would take at that rate.
 *
 * Every run also prints a series of (keyframes, entries, RSS kB, open fds)
 * samples, and for a generated scene the objects the first pass missed
 * (matched to the scene's ground truth) and whether the loop mapped them.
 *
 * --gate-*: the creation gate's model.gate_* (0 = default, -1 = that test off);
 * --log debug prints the gate's verdict on every new slot (docs/cogmap.md).
 *
 * Run from the repository root (the default model path is relative to it). */
#include "sooc3d/gen.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/node.h"

#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

static long rss_kb(void) {
    FILE *f = fopen("/proc/self/status", "r");
    if (!f) return -1;
    char line[256];
    long kb = -1;
    while (fgets(line, sizeof line, f))
        if (!strncmp(line, "VmRSS:", 6)) kb = strtol(line + 6, NULL, 10);
    fclose(f);
    return kb;
}

static int open_fds(void) {
    DIR *d = opendir("/proc/self/fd");
    if (!d) return -1;
    int n = 0;
    struct dirent *e;
    while ((e = readdir(d)))
        if (e->d_name[0] != '.') n++;
    closedir(d);
    return n - 1;   /* the directory stream itself */
}

#define SERIES_MAX 64

typedef struct mon {
    sooc_node *node;
    atomic_int done;
    uint64_t first_pass_kf, tenth_kf;
    uint64_t entries_first, entries_max, entries_tenth, entries_min;   /* min: after the first pass */
    long rss_first, rss_tenth;
    int fds_first, fds_tenth;
    int have_first, have_tenth;
    uint64_t per_k[101];   /* entries at every 1,000th keyframe (per_k[i]: i x 1,000), up to 10^5 */
    int n_per_k;
    uint64_t series_step;  /* a sample of (keyframes, entries, RSS, fds) every series_step keyframes */
    long series[SERIES_MAX][4];
    int n_series;
} mon;

static void *monitor(void *arg) {
    mon *m = arg;
    while (!atomic_load(&m->done)) {
        sooc_node_stats s;
        sooc_node_get_stats(m->node, &s);
        if (s.n_objects > m->entries_max) m->entries_max = s.n_objects;
        if (m->have_first && s.n_objects < m->entries_min) m->entries_min = s.n_objects;
        while (m->n_per_k < 101 && s.keyframes >= (uint64_t)m->n_per_k * 1000) m->per_k[m->n_per_k++] = s.n_objects;
        if (m->series_step && m->n_series < SERIES_MAX && s.keyframes >= (uint64_t)m->n_series * m->series_step) {
            long *r = m->series[m->n_series++];
            r[0] = (long)s.keyframes, r[1] = (long)s.n_objects, r[2] = rss_kb(), r[3] = open_fds();
        }
        if (!m->have_first && s.keyframes >= m->first_pass_kf) {
            m->entries_first = m->entries_min = s.n_objects;
            m->rss_first = rss_kb();
            m->fds_first = open_fds();
            m->have_first = 1;
        }
        if (!m->have_tenth && s.keyframes >= m->tenth_kf) {
            m->entries_tenth = s.n_objects;
            m->rss_tenth = rss_kb();
            m->fds_tenth = open_fds();
            m->have_tenth = 1;
        }
        usleep(20000);
    }
    return NULL;
}

/* Ground truth of a map: the entries of db against the scene's objects. */
#define GT_MAX_OBJ 256
typedef struct gt_score {
    int entries, objects, mapped, dups, far;
    double med_dist;   /* median distance of the entries within reach to their object (m) */
    int hit[GT_MAX_OBJ];   /* entries mapping each object (the first GT_MAX_OBJ) */
} gt_score;
typedef struct gt_visit {
    const sooc_scene *sc;
    int *hits, n;
    double d[4096];
} gt_visit;
#define GT_REACH 0.6

static int gt_visit_fn(void *user, const sooc_cogmap_entry *e) {
    gt_visit *g = user;
    int best = -1;
    double bd = 1e30;
    for (int i = 0; i < g->sc->n_objects; i++) {
        double d = hypot(e->X - g->sc->objects[i].x, e->Z - g->sc->objects[i].z);
        if (d < bd) bd = d, best = i;
    }
    if (best >= 0 && bd < GT_REACH) {
        g->hits[best]++;
        if (g->n < 4096) g->d[g->n++] = bd;
    } else
        g->hits[g->sc->n_objects]++;
    return 0;
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

static int gt_score_db(const sooc_scene *sc, const char *db, gt_score *out) {
    memset(out, 0, sizeof *out);
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.readonly = 1;
    sooc_mapstore *ms = NULL;
    if (sooc_mapstore_open(&ms, db, &mp)) return 1;
    static gt_visit g;
    memset(&g, 0, sizeof g);
    g.sc = sc;
    g.hits = calloc((size_t)sc->n_objects + 1, sizeof *g.hits);
    if (!g.hits) {
        sooc_mapstore_close(ms);
        return 1;
    }
    sooc_status st = sooc_mapstore_foreach(ms, gt_visit_fn, &g);
    sooc_mapstore_close(ms);
    out->objects = sc->n_objects;
    out->far = g.hits[sc->n_objects];
    out->entries = out->far;
    for (int i = 0; i < sc->n_objects; i++) {
        if (i < GT_MAX_OBJ) out->hit[i] = g.hits[i];
        out->entries += g.hits[i];
        out->mapped += g.hits[i] > 0;
        out->dups += g.hits[i] > 1 ? g.hits[i] - 1 : 0;
    }
    qsort(g.d, (size_t)g.n, sizeof *g.d, cmp_double);
    out->med_dist = g.n ? g.d[g.n / 2] : 0.0;
    free(g.hits);
    return st != SOOC_OK;
}

/* The node's configuration: the generated scene (seq NULL: its frame is the
 * world's, floor at 0) or a recorded sequence (its support plane estimated). */
static int node_config(sooc_node_config *c, const char *gen_dir, const char *seq, int loop, const char *model,
                       const char *db, double merge, double clip, const double gate[3], int slots, sooc_log_level lvl) {
    char text[2048];
    int len = snprintf(text, sizeof text,
                       "sensor: {driver: replay, path: '%s%s', speed: fast, loop: %s}\n"
                       "pose: {source: sensor}\n"
                       "model: {path: '%s'}\n"
                       "keyframe: {translation_m: 0.25, rotation_deg: 15, time_s: 0}\n"
                       "map: {db: '%s', resume: true}\n"
                       "world: %s\n"
                       "pipeline: {block_when_full: true, stats_period_s: 0}\n"
                       "log: {level: warn}\n",
                       seq ? seq : gen_dir, seq ? "" : "/scene_0000", loop ? "true" : "false", model, db,
                       seq ? "{floor: estimate}" : "{up: +y, floor: 0.0}");
    if (sooc_node_config_parse(c, text, (size_t)len, "bench_soak.yaml")) {
        fprintf(stderr, "bench_soak: %s\n", sooc_errmsg());
        return 1;
    }
    if (merge >= 0) c->merge_m = merge;
    if (clip > 0) c->clip_m = clip;
    c->gate_min_rays = gate[0];
    c->gate_ratio = gate[1];
    c->gate_part = gate[2];
    c->slots = slots;
    c->log_level = lvl;
    return 0;
}

static void log_stderr(void *user, sooc_log_level level, const char *msg) {
    (void)user;
    (void)level;
    fprintf(stderr, "%s\n", msg);
}

int soak_list(int argc, char **argv);   /* bench_soak_list.c */

int main(int argc, char **argv) {
    for (int i = 1; i < argc; i++)
        if (!strcmp(argv[i], "--list")) return soak_list(argc, argv);
    long long keyframes = 10000;
    const char *scale = "m", *model = "models/sooc3d_unity/model.bin", *out = NULL;
    uint64_t seed = 7;
    double merge = -1, clip = 0, gate[3] = {0, 0, 0};
    const char *seq = NULL;   /* --seq: a recorded sequence instead of a generated scene */
    int slots = 0;            /* --slots: model.slots (0 = the model's K) */
    sooc_log_level lvl = SOOC_LOG_WARN;
    for (int i = 1; i < argc; i++) {
        if (!strcmp(argv[i], "--keyframes") && i + 1 < argc) keyframes = atoll(argv[++i]);
        else if (!strcmp(argv[i], "--scale") && i + 1 < argc) scale = argv[++i];
        else if (!strcmp(argv[i], "--seed") && i + 1 < argc) seed = strtoull(argv[++i], NULL, 10);
        else if (!strcmp(argv[i], "--seq") && i + 1 < argc) seq = argv[++i];
        else if (!strcmp(argv[i], "--slots") && i + 1 < argc) slots = atoi(argv[++i]);
        else if (!strcmp(argv[i], "--merge") && i + 1 < argc) merge = atof(argv[++i]);
        else if (!strcmp(argv[i], "--clip") && i + 1 < argc) clip = atof(argv[++i]);
        else if (!strcmp(argv[i], "--model") && i + 1 < argc) model = argv[++i];
        else if (!strcmp(argv[i], "--out") && i + 1 < argc) out = argv[++i];
        else if (!strcmp(argv[i], "--gate-min") && i + 1 < argc) gate[0] = atof(argv[++i]);
        else if (!strcmp(argv[i], "--gate-ratio") && i + 1 < argc) gate[1] = atof(argv[++i]);
        else if (!strcmp(argv[i], "--gate-part") && i + 1 < argc) gate[2] = atof(argv[++i]);
        else if (!strcmp(argv[i], "--log") && i + 1 < argc && !sooc_log_level_parse(argv[i + 1], &lvl)) i++;
        else {
            fprintf(stderr, "usage: bench_soak [--keyframes N] [--scale s|m|l] [--seed S] [--seq PATH] [--slots K] [--merge R] [--clip M] "
                            "[--model P] [--out DIR] [--gate-min F] [--gate-ratio F] [--gate-part F] "
                            "[--log debug|info|warn]\n");
            return 2;
        }
    }
    if (keyframes < 1) keyframes = 1;
    if (access(model, R_OK)) {
        fprintf(stderr, "bench_soak: no model at %s (run from the repository root)\n", model);
        return 2;
    }
    char dir[512];
    if (out) {
        snprintf(dir, sizeof dir, "%s", out);
        if (mkdir(dir, 0755) && errno != EEXIST) {
            fprintf(stderr, "bench_soak: cannot create %s: %s\n", dir, strerror(errno));
            return 1;
        }
    }
    else {
        snprintf(dir, sizeof dir, "/tmp/bench_soak_XXXXXX");
        if (!mkdtemp(dir)) return 1;
    }
    sooc_gen_params gp;
    sooc_gen_params_default(&gp);
    gp.preset = SOOC_GEN_UNITY;
    gp.scale = !strcmp(scale, "s") ? SOOC_GEN_S : !strcmp(scale, "l") ? SOOC_GEN_L : SOOC_GEN_M;
    gp.seed = seed;
    gp.n_scenes = 1;
    gp.threads = 1;
    gp.write_meshes = 0;
    gp.contact_sheet = 0;
    char gen_dir[600], db[700];
    snprintf(gen_dir, sizeof gen_dir, "%s/gen", dir);
    if (seq && access(seq, R_OK)) {
        fprintf(stderr, "bench_soak: SKIP: no sequence at %s\n", seq);
        return 77;
    }
    if (!seq && sooc_gen_run(&gp, gen_dir, NULL, NULL, NULL)) {
        fprintf(stderr, "bench_soak: gen: %s\n", sooc_errmsg());
        return 1;
    }
    /* a generated pass replays the input and the query views; a recording's
     * pass length is the reference pass's keyframe count (below) */
    int views = 0;
    if (!seq) {
        views = sooc_gen_views(&gp);
        views += gp.n_query >= 0 ? gp.n_query : (views / 5 > 2 ? views / 5 : 2);
    }
    sooc_log_set_level(lvl);
    sooc_log_set_callback(log_stderr, NULL);
    /* the reference: one pass into its own map */
    char db1[700];
    snprintf(db1, sizeof db1, "%s/map_pass1.sqlite", dir);
    sooc_node_config c;
    if (node_config(&c, gen_dir, seq, !seq, model, db1, merge, clip, gate, slots, lvl)) return 1;
    sooc_node_options o;
    memset(&o, 0, sizeof o);
    o.max_keyframes = (uint64_t)views;   /* a recorded sequence: to its end */
    sooc_node *n = NULL;
    if (sooc_node_create(&n, &c, &o) || sooc_node_run(n)) {
        fprintf(stderr, "bench_soak: one pass: %s\n", sooc_errmsg());
        sooc_node_destroy(n);
        return 1;
    }
    if (seq) {
        sooc_node_stats s1;
        sooc_node_get_stats(n, &s1);
        views = (int)s1.keyframes;
        if (views < 1) {
            fprintf(stderr, "bench_soak: %s: one pass mapped no keyframe\n", seq);
            sooc_node_destroy(n);
            return 1;
        }
    }
    sooc_node_destroy(n);
    n = NULL;
    snprintf(db, sizeof db, "%s/map.sqlite", dir);
    if (node_config(&c, gen_dir, seq, 1, model, db, merge, clip, gate, slots, lvl)) return 1;
    long rss0 = rss_kb();
    int fds0 = open_fds();
    o.max_keyframes = (uint64_t)keyframes;
    if (sooc_node_create(&n, &c, &o)) {
        fprintf(stderr, "bench_soak: %s\n", sooc_errmsg());
        return 1;
    }
    mon m;
    memset(&m, 0, sizeof m);
    m.node = n;
    atomic_init(&m.done, 0);
    m.first_pass_kf = (uint64_t)views;
    m.tenth_kf = (uint64_t)(keyframes / 10 > views ? keyframes / 10 : views);
    m.series_step = (uint64_t)((keyframes + 31) / 32);
    pthread_t th;
    pthread_create(&th, NULL, monitor, &m);
    double t0 = sooc_seconds();
    sooc_status st = sooc_node_run(n);
    double secs = sooc_seconds() - t0;
    atomic_store(&m.done, 1);
    pthread_join(th, NULL);
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    long rss_end = rss_kb();
    int fds_end = open_fds();
    if (st) fprintf(stderr, "bench_soak: run: %s\n", sooc_errmsg());
    char perk[101 * 24] = "";
    size_t pl = 0;
    for (int i = 1; i < m.n_per_k && pl + 24 < sizeof perk; i++)
        pl += (size_t)snprintf(perk + pl, sizeof perk - pl, "%s%llu", i > 1 ? ", " : "", (unsigned long long)m.per_k[i]);
    sooc_node_destroy(n);
    int fds_after = open_fds();
    double growth = m.entries_first ? (double)s.n_objects / (double)m.entries_first - 1.0 : 0.0;
    sooc_scene sc;
    sooc_scene_init(&sc);
    gt_score g1, g2;
    memset(&g1, 0, sizeof g1);
    memset(&g2, 0, sizeof g2);
    if (!seq && (sooc_gen_scene(&sc, &gp, 0) || gt_score_db(&sc, db1, &g1) || gt_score_db(&sc, db, &g2)))
        fprintf(stderr, "bench_soak: ground truth: %s\n", sooc_errmsg());
    char gt[512] = "\"gt_objects\": null, \"gt_one_pass\": null, \"gt_end\": null";
    /* the objects the first pass missed, and whether the loop mapped them */
    static char missed[64 * 160];
    size_t ml = 0;
    int n_missed = 0, n_gained = 0;
    ml += (size_t)snprintf(missed, sizeof missed, "\"missed_first_pass\": %s", seq ? "null" : "[");
    for (int i = 0; !seq && i < g1.objects && i < GT_MAX_OBJ; i++) {
        if (g1.hit[i] || ml + 160 >= sizeof missed) continue;
        const sooc_scene_object *ob = &sc.objects[i];
        ml += (size_t)snprintf(missed + ml, sizeof missed - ml,
                               "%s{\"object\": %d, \"shape\": \"%s\", \"x\": %.3f, \"z\": %.3f, \"mapped_at_end\": %s}",
                               n_missed ? ", " : "", ob->id, sooc_shape_name(ob->shape), ob->x, ob->z,
                               g2.hit[i] ? "true" : "false");
        n_missed++;
        n_gained += g2.hit[i] > 0;
    }
    if (!seq) snprintf(missed + ml, sizeof missed - ml, "], \"gained_from_missed\": %d", n_gained);
    else snprintf(missed + ml, sizeof missed - ml, ", \"gained_from_missed\": null");
    char series[SERIES_MAX * 64] = "";
    size_t sl = 0;
    for (int i = 0; i < m.n_series && sl + 64 < sizeof series; i++)
        sl += (size_t)snprintf(series + sl, sizeof series - sl, "%s[%ld, %ld, %ld, %ld]", i ? ", " : "", m.series[i][0],
                               m.series[i][1], m.series[i][2], m.series[i][3]);
    if (!seq) {
        snprintf(gt, sizeof gt,
                 "\"gt_objects\": %d, \"gt_one_pass\": {\"entries\": %d, \"objects\": %d, \"duplicates\": %d, "
                 "\"far\": %d, \"median_offset_m\": %.4f}, \"gt_end\": {\"entries\": %d, \"objects\": %d, "
                 "\"duplicates\": %d, \"far\": %d, \"median_offset_m\": %.4f}",
                 g1.objects, g1.entries, g1.mapped, g1.dups, g1.far, g1.med_dist, g2.entries, g2.mapped, g2.dups, g2.far,
                 g2.med_dist);
        fprintf(stderr,
                "bench_soak: ground truth (%d objects): one pass %d entries = %d objects + %d duplicates + %d far, "
                "median %.3f m off; loop end %d = %d + %d + %d, median %.3f m off\n",
                g1.objects, g1.entries, g1.mapped, g1.dups, g1.far, g1.med_dist, g2.entries, g2.mapped, g2.dups, g2.far,
                g2.med_dist);
    }
    fprintf(stderr,
            "bench_soak: %llu keyframes in %.0f s, entries %llu after the first pass (%d views), %llu at the end "
            "(%+.1f%%), max %llu, min %llu; RSS %ld -> %ld -> %ld kB; fds %d -> %d -> %d (%d after destroy)\n",
            (unsigned long long)s.keyframes, secs, (unsigned long long)m.entries_first, views,
            (unsigned long long)s.n_objects, 100 * growth, (unsigned long long)m.entries_max,
            (unsigned long long)m.entries_min, m.rss_first,
            m.rss_tenth, rss_end, m.fds_first, m.fds_tenth, fds_end, fds_after);
    printf("{\"bench\": \"soak\", \"scale\": \"%s\", \"seed\": %llu, \"seq\": \"%s\", \"views_per_pass\": %d, \"merge_m\": %g, \"clip_m\": %g, "
           "\"gate\": [%g, %g, %g], \"slots\": %d, "
           "\"keyframes\": %llu, \"seconds\": %.1f, \"entries_first_pass\": %llu, \"entries_tenth\": %llu, "
           "\"entries_end\": %llu, \"entries_max\": %llu, \"entries_min\": %llu, \"entries_per_1000\": [%s], \"growth_vs_first_pass\": %.4f, \"rss_kb_start\": %ld, "
           "\"rss_kb_first_pass\": %ld, \"rss_kb_tenth\": %ld, \"rss_kb_end\": %ld, \"fds_start\": %d, "
           "\"fds_first_pass\": %d, \"fds_tenth\": %d, \"fds_end\": %d, \"fds_after_destroy\": %d, "
           "\"series_kf_entries_rss_fds\": [%s], %s, %s, \"status\": \"%s\"}\n",
           seq ? "real" : scale, (unsigned long long)seed, seq ? seq : "", views, c.merge_m, c.clip_m, gate[0], gate[1], gate[2], c.slots,
           (unsigned long long)s.keyframes, secs,
           (unsigned long long)m.entries_first, (unsigned long long)m.entries_tenth, (unsigned long long)s.n_objects,
           (unsigned long long)m.entries_max, (unsigned long long)m.entries_min, perk, growth, rss0, m.rss_first, m.rss_tenth, rss_end, fds0, m.fds_first,
           m.fds_tenth, fds_end, fds_after, series, missed, gt, sooc_status_str(st));
    sooc_scene_free(&sc);
    if (!out) {
        char cmd[600];
        snprintf(cmd, sizeof cmd, "rm -rf '%s'", dir);
        if (system(cmd)) fprintf(stderr, "bench_soak: could not remove %s\n", dir);
    }
    return st ? 1 : 0;
}
