/* In-memory scene datasets for training and validation. Frames are read
 * through the one frame path (include/sooc3d/frame.h): any resolution,
 * cropped/resized to the model's, poses in the map's world frame. */
#include "sooc3d/train.h"
#include "sooc3d/frame.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/gen.h"

#include <dirent.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct ds_scene {
    char *path;
    int n_views, n_inputs;
    sooc_frame *views;          /* n_views, trajectory order       */
    int *input_idx;             /* n_inputs indices into views     */
    int n_obj;
    uint16_t *obj_id;
    double *obj_xz;             /* n_obj x 2                       */
    int recorded;               /* 1: a recorded sequence (no scene.yaml) */
    int *cand_idx;              /* recorded: views that may be inputs or queries
                                   (every view but the held-out ones)      */
    int n_cand;
} ds_scene;

struct sooc_dataset {
    int n, cap;
    ds_scene *scenes;
    double unit_m;   /* the model's metres per unit for the query choice (0 = 1) */
    sooc_dataset_rec_params rec;
    int n_recorded;
};

void sooc_dataset_rec_params_default(sooc_dataset_rec_params *p) {
    memset(p, 0, sizeof *p);
    p->view_min_cm = SOOC_DATASET_VIEW_MIN_CM;
    p->view_min_deg = SOOC_DATASET_VIEW_MIN_DEG;
    p->held_out_every = SOOC_DATASET_QUERY_EVERY;
    p->world_dir = NULL;
}

void sooc_dataset_set_unit(sooc_dataset *d, double unit_m) { d->unit_m = unit_m > 0 ? unit_m : 0; }

static void scene_free(ds_scene *s) {
    for (int i = 0; i < s->n_views; i++) sooc_frame_free(&s->views[i]);
    sooc_free(s->views);
    sooc_free(s->input_idx);
    sooc_free(s->obj_id);
    sooc_free(s->obj_xz);
    sooc_free(s->cand_idx);
    sooc_free(s->path);
    memset(s, 0, sizeof *s);
}

void sooc_dataset_destroy(sooc_dataset *d) {
    if (!d) return;
    for (int i = 0; i < d->n; i++) scene_free(&d->scenes[i]);
    sooc_free(d->scenes);
    sooc_free(d);
}

/* Two camera poses (T_wc, row-major) differ by at least min_cm in centre
 * position or at least min_deg between their optical axes. */
static int views_distinct(const double *A, const double *B, double min_cm, double min_deg) {
    double dx = A[3] - B[3], dy = A[7] - B[7], dz = A[11] - B[11];
    if (100.0 * sqrt(dx * dx + dy * dy + dz * dz) >= min_cm) return 1;
    double c = A[2] * B[2] + A[6] * B[6] + A[10] * B[10];
    c = c > 1 ? 1 : c < -1 ? -1 : c;
    return acos(c) * (180.0 / M_PI) >= min_deg;
}

/* Map database that keeps a recorded sequence's world frame (support plane)
 * for the next run: world_dir/world_<name>_<hash of the path>.sqlite. */
static sooc_status world_db_path(char *buf, size_t cap, const char *world_dir, const char *dir) {
    size_t n = strlen(dir);
    while (n > 1 && dir[n - 1] == '/') n--;
    size_t b = n;
    while (b > 0 && dir[b - 1] != '/') b--;
    uint32_t h = 2166136261u;   /* FNV-1a of the path as given */
    for (size_t i = 0; i < n; i++) h = (h ^ (uint8_t)dir[i]) * 16777619u;
    char name[160];
    int k = 0;
    for (size_t i = b; i < n && k < 100; i++) {
        char ch = dir[i];
        name[k++] = (ch >= 'a' && ch <= 'z') || (ch >= 'A' && ch <= 'Z') || (ch >= '0' && ch <= '9') || ch == '-' ? ch : '_';
    }
    name[k] = 0;
    int w = snprintf(buf, cap, "%s/world_%s_%08x.sqlite", world_dir, name, (unsigned)h);
    if (w < 0 || (size_t)w >= cap) return sooc_seterr(SOOC_EINVAL, "%s: path too long", world_dir);
    return SOOC_OK;
}

/* Store a fresh support-plane estimate where the next run reads it (as the
 * node stores it in its map, docs/node.md "Support plane"). */
static sooc_status world_store(sooc_framepath *fp, const char *db) {
    sooc_map_frame mf;
    memset(&mf, 0, sizeof mf);
    sooc_framepath_frame_record(fp, mf.T_world_src, mf.up_src, mf.plane_src, &mf.cam_height_m, &mf.up_source);
    sooc_mapstore *ms = NULL;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.dim = mp.layout_dim = 1;   /* no entries are stored, only the frame */
    sooc_status s = sooc_mapstore_open(&ms, db, &mp);
    if (!s) s = sooc_mapstore_frame_put(ms, &mf);
    sooc_mapstore_close(ms);
    if (s) return sooc_adderr(s, "%s: storing the world frame", db);
    sooc_log(SOOC_LOG_INFO, "%s: world frame stored in %s", sooc_framepath_dir(fp), db);
    return SOOC_OK;
}

/* Input views of a recorded sequence: a keyframe chain over the views that
 * are not held out, each distinct (views_distinct) from the previous one. */
static void recorded_chain(ds_scene *sc, const sooc_dataset_rec_params *rp) {
    sc->n_inputs = 0;
    int last = -1;
    for (int c = 0; c < sc->n_cand; c++) {
        int v = sc->cand_idx[c];
        if (last >= 0 && !views_distinct(sc->views[v].T_wc, sc->views[last].T_wc, rp->view_min_cm, rp->view_min_deg))
            continue;
        sc->input_idx[sc->n_inputs++] = v;
        last = v;
    }
}

/* Load one scene directory: a synthetic scene (scene.yaml + TUM layout) or a
 * recorded sequence (no scene.yaml: no objects; the frames at sequence
 * positions p with p % held_out_every == held_out_every / 2 are held out
 * (is_query, never sampled for training), frames without a pose skipped;
 * inputs by recorded_chain). */
static sooc_status load_scene(ds_scene *out, const char *dir, const sooc_framepath_params *fpp0,
                              const sooc_dataset_rec_params *rp) {
    memset(out, 0, sizeof *out);
    char path[4096], db[4096];
    sooc_status s = sooc_path_join(path, sizeof path, dir, "scene.yaml");
    if (s) return s;
    int synthetic = sooc_file_exists(path);
    sooc_framepath_params fpp = *fpp0;
    int store = 0;   /* 1: store a fresh estimate in db */
    if (!synthetic && rp->world_dir && rp->world_dir[0] && !fpp.map_db && fpp.world == SOOC_WORLD_AUTO) {
        if ((s = world_db_path(db, sizeof db, rp->world_dir, dir))) return s;
        if (sooc_file_exists(db)) fpp.map_db = db;   /* reused: a frame stored by an earlier run */
        else store = 1;
    }
    sooc_scene sc;
    sooc_scene_init(&sc);
    if (synthetic && (s = sooc_scene_load(path, &sc))) return s;
    sooc_framepath *fp = NULL;
    s = sooc_framepath_open(&fp, dir, &fpp);
    if (s) { sooc_scene_free(&sc); return s; }
    if (store && sooc_framepath_world_get(fp, NULL) == SOOC_WORLD_ESTIMATE && (s = world_store(fp, db)))
        goto done;
    int64_t n = sooc_framepath_count(fp);
    if (n <= 0 || n > 100000) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: %lld views", dir, (long long)n);
        goto done;
    }
    out->path = sooc_strdup(dir);
    out->recorded = !synthetic;
    out->views = sooc_calloc((size_t)n, sizeof(sooc_frame));
    out->input_idx = sooc_calloc((size_t)n, sizeof(int));
    out->cand_idx = sooc_calloc((size_t)n, sizeof(int));
    out->obj_id = sooc_calloc((size_t)sc.n_objects + 1, sizeof(uint16_t));
    out->obj_xz = sooc_calloc((size_t)sc.n_objects + 1, 2 * sizeof(double));
    if (!out->path || !out->views || !out->input_idx || !out->cand_idx || !out->obj_id || !out->obj_xz) {
        s = SOOC_ENOMEM;
        goto done;
    }
    int every = rp->held_out_every;
    for (int64_t i = 0; i < n; i++) {
        int v = out->n_views;
        sooc_frame *f = &out->views[v];
        s = sooc_framepath_read(fp, i, f);
        out->n_views = v + 1;
        if (s) goto done;
        if (!f->has_pose) {
            if (synthetic) {
                s = sooc_seterr(SOOC_EFORMAT, "%s: view %lld has no pose", dir, (long long)i);
                goto done;
            }
            sooc_frame_free(f);
            out->n_views = v;
            continue;
        }
        if (synthetic) {
            if (sc.view_is_query && i < sc.n_views) f->is_query = sc.view_is_query[i];
            if (!f->is_query) out->input_idx[out->n_inputs++] = v;
        } else {
            /* the position in the sequence, as `sooc3d eval` counts it */
            f->is_query = every >= 2 && i % every == every / 2;
            if (!f->is_query) out->cand_idx[out->n_cand++] = v;
        }
    }
    if (!synthetic) recorded_chain(out, rp);
    if (out->n_inputs == 0) {
        s = sooc_seterr(SOOC_EFORMAT, "%s: no input views", dir);
        goto done;
    }
    out->n_obj = sc.n_objects;
    for (int i = 0; i < sc.n_objects; i++) {
        double c[3];
        sooc_scene_object_center(&sc.objects[i], c);
        out->obj_id[i] = (uint16_t)sc.objects[i].id;
        out->obj_xz[2 * i] = c[0];
        out->obj_xz[2 * i + 1] = c[2];
    }
done:
    sooc_framepath_close(fp);
    sooc_scene_free(&sc);
    if (s) scene_free(out);
    return s;
}

static int cmp_str(const void *a, const void *b) { return strcmp(*(char *const *)a, *(char *const *)b); }

static sooc_status push_scene(sooc_dataset *d, const char *dir, const sooc_framepath_params *fpp) {
    if (d->n == d->cap) {
        int cap = d->cap ? 2 * d->cap : 16;
        ds_scene *ns = sooc_realloc(d->scenes, (size_t)cap * sizeof(ds_scene));
        if (!ns) return SOOC_ENOMEM;
        d->scenes = ns;
        d->cap = cap;
    }
    sooc_status s = load_scene(&d->scenes[d->n], dir, fpp, &d->rec);
    if (s) return s;
    d->n_recorded += d->scenes[d->n].recorded;
    d->n++;
    return SOOC_OK;
}

static sooc_status add_dir(sooc_dataset *d, const char *dir, const sooc_framepath_params *fpp) {
    char path[4096];
    sooc_status s = sooc_path_join(path, sizeof path, dir, "scene.yaml");
    if (s) return s;
    if (sooc_file_exists(path)) return push_scene(d, dir, fpp);
    DIR *dp = opendir(dir);
    if (!dp) return sooc_seterr(SOOC_ENOTFOUND, "%s: not a scene or a directory of scenes", dir);
    char **names = NULL;
    int n = 0, cap = 0;
    struct dirent *e;
    s = SOOC_OK;
    while ((e = readdir(dp))) {
        if (strncmp(e->d_name, "scene_", 6) != 0) continue;
        if (n == cap) {
            cap = cap ? 2 * cap : 64;
            char **nn = sooc_realloc(names, (size_t)cap * sizeof(char *));
            if (!nn) { s = SOOC_ENOMEM; break; }
            names = nn;
        }
        names[n] = sooc_strdup(e->d_name);
        if (!names[n]) { s = SOOC_ENOMEM; break; }
        n++;
    }
    closedir(dp);
    if (!s) {
        if (n > 0) qsort(names, (size_t)n, sizeof(char *), cmp_str);   /* names is NULL when n == 0 */
        for (int i = 0; i < n && !s; i++) {
            if ((s = sooc_path_join(path, sizeof path, dir, names[i]))) break;
            s = push_scene(d, path, fpp);
        }
        if (!s && n == 0) {
            /* a recorded sequence (7-Scenes, label-fusion, TUM, ...) is one scene */
            s = push_scene(d, dir, fpp);
            if (s) sooc_adderr(s, "%s: no scene.yaml, no scene_* folders, and not a readable sequence", dir);
        }
    }
    for (int i = 0; i < n; i++) sooc_free(names[i]);
    sooc_free(names);
    return s;
}

sooc_status sooc_dataset_open(sooc_dataset **out, const char *const *dirs, int n_dirs, int width,
                              int height) {
    sooc_framepath_params fpp;
    sooc_framepath_params_default(&fpp);
    fpp.width = width, fpp.height = height;
    return sooc_dataset_open_fp(out, dirs, n_dirs, &fpp);
}

sooc_status sooc_dataset_open_fp(sooc_dataset **out, const char *const *dirs, int n_dirs,
                                 const sooc_framepath_params *fpp) {
    return sooc_dataset_open_rec(out, dirs, n_dirs, fpp, NULL);
}

sooc_status sooc_dataset_open_rec(sooc_dataset **out, const char *const *dirs, int n_dirs,
                                  const sooc_framepath_params *fpp, const sooc_dataset_rec_params *rp) {
    *out = NULL;
    if (!fpp || fpp->width <= 0 || fpp->height <= 0)
        return sooc_seterr(SOOC_EINVAL, "dataset: the frame path needs the model's resolution");
    sooc_dataset_rec_params def;
    sooc_dataset_rec_params_default(&def);
    if (!rp) rp = &def;
    if (!(rp->view_min_cm >= 0 && rp->view_min_cm <= 1e4 && rp->view_min_deg >= 0 && rp->view_min_deg <= 180))
        return sooc_seterr(SOOC_EINVAL, "dataset: view baseline %g cm / %g deg out of range (0..1e4 cm, 0..180 deg)",
                           rp->view_min_cm, rp->view_min_deg);
    if (rp->held_out_every == 1 || rp->held_out_every < 0)
        return sooc_seterr(SOOC_EINVAL, "dataset: held-out rule N = %d (0 = none, else >= 2)", rp->held_out_every);
    if (rp->world_dir && rp->world_dir[0]) {
        sooc_status s = sooc_mkdirs(rp->world_dir);
        if (s) return sooc_adderr(s, "dataset: world-frame folder %s", rp->world_dir);
    }
    sooc_dataset *d = sooc_calloc(1, sizeof *d);
    if (!d) return SOOC_ENOMEM;
    d->rec = *rp;
    for (int i = 0; i < n_dirs; i++) {
        sooc_status s = add_dir(d, dirs[i], fpp);
        if (s) { sooc_dataset_destroy(d); return s; }
    }
    if (d->n == 0) {
        sooc_dataset_destroy(d);
        return sooc_seterr(SOOC_ENOTFOUND, "no scenes found");
    }
    *out = d;
    return SOOC_OK;
}

int sooc_dataset_scene_recorded(const sooc_dataset *d, int s) { return d->scenes[s].recorded; }
int sooc_dataset_n_recorded(const sooc_dataset *d) { return d->n_recorded; }

int sooc_dataset_pick(const sooc_dataset *d, double recorded_frac, sooc_rng *rng) {
    int nr = d->n_recorded, ns = d->n - d->n_recorded;
    if (!(recorded_frac > 0) || nr == 0 || ns == 0) return (int)sooc_rng_below(rng, (uint32_t)d->n);
    int rec = sooc_rng_uniform(rng) < recorded_frac;
    int k = (int)sooc_rng_below(rng, (uint32_t)(rec ? nr : ns));
    for (int i = 0; i < d->n; i++)
        if (d->scenes[i].recorded == rec && k-- == 0) return i;
    return d->n - 1;   /* not reached */
}

int sooc_dataset_n_scenes(const sooc_dataset *d) { return d->n; }
const char *sooc_dataset_scene_path(const sooc_dataset *d, int s) { return d->scenes[s].path; }
int sooc_dataset_n_views(const sooc_dataset *d, int s) { return d->scenes[s].n_views; }
const sooc_frame *sooc_dataset_view(const sooc_dataset *d, int s, int v) { return &d->scenes[s].views[v]; }
int sooc_dataset_cam_heights(const sooc_dataset *d, double *lo, double *hi) {
    int n = 0;
    *lo = *hi = 0;
    for (int s = 0; s < d->n; s++)
        for (int v = 0; v < d->scenes[s].n_views; v++) {
            const sooc_frame *f = &d->scenes[s].views[v];
            if (!f->has_pose) continue;
            double h = f->T_wc[7];
            if (!n || h < *lo) *lo = h;
            if (!n || h > *hi) *hi = h;
            n++;
        }
    return n;
}
int sooc_dataset_n_inputs(const sooc_dataset *d, int s) { return d->scenes[s].n_inputs; }
int sooc_dataset_n_objects(const sooc_dataset *d, int s) { return d->scenes[s].n_obj; }
void sooc_dataset_object(const sooc_dataset *d, int s, int i, uint16_t *id, double *x, double *z) {
    const ds_scene *sc = &d->scenes[s];
    *id = sc->obj_id[i];
    *x = sc->obj_xz[2 * i];
    *z = sc->obj_xz[2 * i + 1];
}

/* Query views of mode 0: the Q query frames whose camera centre is nearest
 * (on the floor) to any camera of the chosen segment, so that they look at
 * what the segment mapped. Ties go to the lower index: deterministic. */
static int sample_nearest(const ds_scene *sc, const sooc_frame *views, int T, int Q, double unit_m,
                          sooc_frame *queries) {
    double iu = unit_m > 0 ? 1.0 / unit_m : 1.0;   /* distances in model units */
    int nq = 0;
    int used[64] = {0};
    for (int q = 0; q < Q; q++) {
        double best = INFINITY;
        int best_v = -1, ci = -1, best_ci = -1;
        for (int v = 0; v < sc->n_views; v++) {
            if (!sc->views[v].is_query) continue;
            if (++ci >= 64) break;
            if (used[ci]) continue;
            const double *Tq = sc->views[v].T_wc;
            for (int t = 0; t < T; t++) {
                const double *Tv = views[t].T_wc;
                double dx = Tq[3] - Tv[3], dz = Tq[11] - Tv[11];
                /* Also prefer a similar heading: 1 model unit (config.unit_m) per radian. */
                double fq = atan2(Tq[2], Tq[10]), fv = atan2(Tv[2], Tv[10]);
                double da = fabs(remainder(fq - fv, 2 * M_PI));
                double dist = sqrt(dx * dx + dz * dz) * iu + da;
                if (dist < best) { best = dist; best_v = v; best_ci = ci; }
            }
        }
        if (best_v < 0) break;
        used[best_ci] = 1;
        queries[nq++] = sc->views[best_v];
    }
    return nq;
}

/* Query views of mode 1 (held-out views): any view of the scene outside the
 * segment (query-flagged or another input view) that shows at least one
 * object and whose object pixels belong, for at least SOOC_HELD_OUT_COVER of
 * them, to objects the segment saw (>= SEEN_MIN_PX pixels in one of its
 * views). Q of them are drawn at random. These views look at what the segment
 * mapped from other positions and headings than the nearest query frames, so
 * the query term asks for objects as seen from where the walk has not been
 * (docs/training.md "Held-out query views"). Returns 0 when no view qualifies
 * (the caller falls back to mode 0). */
#define SEEN_MIN_PX 16
static int sample_held_out(const ds_scene *sc, int start, int T, int Q, sooc_rng *rng, sooc_frame *queries) {
    uint64_t seen[65536 / 64];
    uint16_t cnt_id[64];
    int cnt_px[64];
    memset(seen, 0, sizeof seen);
    for (int t = 0; t < T; t++) {
        const sooc_frame *f = &sc->views[sc->input_idx[start + t]];
        if (!f->instance) return 0;
        /* per-view pixel counts of up to 64 distinct ids (scenes hold fewer) */
        int n_ids = 0;
        size_t np = (size_t)f->width * (size_t)f->height;
        for (size_t i = 0; i < np; i++) {
            uint16_t id = f->instance[i];
            if (!id || !f->valid[i]) continue;
            int k = 0;
            while (k < n_ids && cnt_id[k] != id) k++;
            if (k == n_ids) {
                if (n_ids == 64) continue;
                cnt_id[n_ids] = id;
                cnt_px[n_ids++] = 0;
            }
            cnt_px[k]++;
        }
        for (int k = 0; k < n_ids; k++)
            if (cnt_px[k] >= SEEN_MIN_PX) seen[cnt_id[k] >> 6] |= 1ull << (cnt_id[k] & 63);
    }
    int cand[256], n_cand = 0;
    int seg_lo = sc->input_idx[start], seg_hi = sc->input_idx[start + T - 1];
    for (int v = 0; v < sc->n_views && n_cand < 256; v++) {
        const sooc_frame *f = &sc->views[v];
        if (v >= seg_lo && v <= seg_hi && !f->is_query) continue;   /* in the segment */
        if (!f->instance) continue;
        size_t np = (size_t)f->width * (size_t)f->height, obj = 0, cov = 0;
        for (size_t i = 0; i < np; i++) {
            uint16_t id = f->instance[i];
            if (!id || !f->valid[i]) continue;
            obj++;
            cov += (seen[id >> 6] >> (id & 63)) & 1;
        }
        if (obj >= SEEN_MIN_PX && (double)cov >= SOOC_HELD_OUT_COVER * (double)obj) cand[n_cand++] = v;
    }
    int nq = 0;
    for (; nq < Q && nq < n_cand; nq++) {   /* partial Fisher-Yates */
        int j = nq + (int)sooc_rng_below(rng, (uint32_t)(n_cand - nq));
        int tmp = cand[nq];
        cand[nq] = cand[j];
        cand[j] = tmp;
        queries[nq] = sc->views[cand[nq]];
    }
    return nq;
}

/* Query views of a recorded sequence: the Q views, among those neither held
 * out nor in the segment, that are distinct (views_distinct) from every
 * input view of the segment and nearest to it (floor distance in model units
 * plus the angle between optical axes in radians, to the nearest segment
 * view), so that they look at what the segment saw from a real baseline.
 * Deterministic; ties go to the lower index. */
static int sample_recorded(const ds_scene *sc, const sooc_frame *views, int T, int Q, double unit_m,
                           const sooc_dataset_rec_params *rp, int seg_lo, int seg_hi, sooc_frame *queries) {
    double iu = unit_m > 0 ? 1.0 / unit_m : 1.0;
    int chosen[16], nq = 0;
    if (Q > 16) Q = 16;
    while (nq < Q) {
        double best = INFINITY;
        int best_v = -1;
        for (int c = 0; c < sc->n_cand; c++) {
            int v = sc->cand_idx[c];
            if (v >= seg_lo && v <= seg_hi) continue;   /* inside the segment's stretch */
            int dup = 0;
            for (int k = 0; k < nq && !dup; k++) dup = chosen[k] == v;
            if (dup) continue;
            const double *Tq = sc->views[v].T_wc;
            double dmin = INFINITY;
            int ok = 1;
            for (int t = 0; t < T && ok; t++) {
                const double *Tv = views[t].T_wc;
                if (!views_distinct(Tq, Tv, rp->view_min_cm, rp->view_min_deg)) { ok = 0; break; }
                double dx = Tq[3] - Tv[3], dz = Tq[11] - Tv[11];
                double ca = Tq[2] * Tv[2] + Tq[6] * Tv[6] + Tq[10] * Tv[10];
                ca = ca > 1 ? 1 : ca < -1 ? -1 : ca;
                double dist = sqrt(dx * dx + dz * dz) * iu + acos(ca);
                if (dist < dmin) dmin = dist;
            }
            if (ok && dmin < best) { best = dmin; best_v = v; }
        }
        if (best_v < 0) break;
        chosen[nq] = best_v;
        queries[nq++] = sc->views[best_v];
    }
    return nq;
}

void sooc_dataset_sample(const sooc_dataset *d, int scene, int T, int Q, int mode, sooc_rng *rng,
                         sooc_frame *views, int *n_views, sooc_frame *queries, int *n_queries) {
    const ds_scene *sc = &d->scenes[scene];
    if (T > sc->n_inputs) T = sc->n_inputs;
    int start = (int)sooc_rng_below(rng, (uint32_t)(sc->n_inputs - T + 1));
    for (int t = 0; t < T; t++) views[t] = sc->views[sc->input_idx[start + t]];
    *n_views = T;
    int nq = 0;
    if (sc->recorded) {   /* documented rule: docs/training.md "Training from recordings" */
        *n_queries = Q > 0 ? sample_recorded(sc, views, T, Q, d->unit_m, &d->rec, sc->input_idx[start],
                                             sc->input_idx[start + T - 1], queries) : 0;
        return;
    }
    if (mode == 1 && Q > 0) nq = sample_held_out(sc, start, T, Q, rng, queries);
    if (nq == 0) nq = sample_nearest(sc, views, T, Q, d->unit_m, queries);
    *n_queries = nq;
}
