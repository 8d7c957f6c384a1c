/* SLAM over the RGB-D odometry: keyframe graph, loop closure, pose-graph
 * optimisation and relocalisation (include/sooc3d/slam.h). */
#include <math.h>
#include <string.h>

#include "sooc3d/core.h"
#include "slam/slam_impl.h"

static const char *const g_states[] = {"first", "tracked", "relocalised", "failed", "lost"};

const char *sooc_slam_state_name(sooc_slam_state s) { return (unsigned)s < 5 ? g_states[s] : "?"; }

void sooc_slam_params_default(sooc_slam_params *p) {
    memset(p, 0, sizeof *p);
    sooc_odom_params_default(&p->odom);
    p->loop_closure = 1;
    p->relocalise = 1;
    p->n_features = 800;
    p->recent_window = 6;
    p->local_edges = 0;
    p->loop_max_dist_m = 1.0;
    p->loop_max_angle_deg = 60;
    p->max_candidates = 3;
    p->loop_verify_per_frame = 1;
    p->min_matches = 40;
    p->min_inliers = 30;
    p->reproj_px = 2.0;
    p->min_icp_agree = 0.6;
    p->min_overlap = 0.3;
    p->max_jump_m = 0.05;
    p->max_jump_deg = 5;
    p->sigma_odom_m = 0.01;
    p->sigma_odom_rad = 0.01;
    p->sigma_loop_m = 0.01;
    p->sigma_loop_rad = 0.01;
    p->depth_w = 160;
    p->depth_h = 120;
    p->pgo_iterations = 50;
}

static sooc_status grow(void **p, int64_t *cap, int64_t need, size_t elem) {
    if (need <= *cap) return SOOC_OK;
    int64_t nc = *cap ? *cap * 2 : 64;
    while (nc < need) nc *= 2;
    void *q = sooc_realloc(*p, (size_t)nc * elem);
    if (!q) return sooc_seterr(SOOC_ENOMEM, "slam: out of memory");
    *p = q;
    *cap = nc;
    return SOOC_OK;
}

static sooc_status grow_i(void **p, int *cap, int need, size_t elem) {
    int64_t c = *cap;
    sooc_status st = grow(p, &c, need, elem);
    *cap = (int)c;
    return st;
}

static sooc_status add_node(sooc_slam *s, sooc_slam_node **out) {
    sooc_status st = grow_i((void **)&s->nodes, &s->cap_nodes, s->n_nodes + 1, sizeof(sooc_slam_node));
    if (st) return st;
    sooc_slam_node *n = &s->nodes[s->n_nodes++];
    memset(n, 0, sizeof *n);
    *out = n;
    return SOOC_OK;
}

static sooc_status add_edge(sooc_slam *s, int a, int b, int kind, const double T_ab[16], double wt, double wr) {
    sooc_status st = grow_i((void **)&s->edges, &s->cap_edges, s->n_edges + 1, sizeof(sooc_slam_edge));
    if (st) return st;
    sooc_slam_edge *e = &s->edges[s->n_edges++];
    e->a = a;
    e->b = b;
    e->kind = kind;
    memcpy(e->T_ab, T_ab, sizeof e->T_ab);
    e->w_t = wt;
    e->w_r = wr;
    if (!s->store) return SOOC_OK;
    sooc_slamdb_edge r = {.a = s->nodes[a].id, .b = s->nodes[b].id, .kind = kind, .w_t = wt, .w_r = wr};
    memcpy(r.T_ab, T_ab, sizeof r.T_ab);
    return sooc_mapstore_slam_put_edge(s->store, &r);
}

/* ------------------------------------------------------- store loading */

typedef struct load_ctx {
    sooc_slam *s;
    sooc_status st;
} load_ctx;

static int load_kf(const sooc_slamdb_kf *k, void *user) {
    load_ctx *c = user;
    sooc_slam_node *n;
    if ((c->st = add_node(c->s, &n))) return 1;
    n->id = k->id;
    n->run = k->run;
    n->frame = k->frame;
    n->t_ns = k->t_ns;
    n->segment = -1;
    memcpy(n->T, k->T_wc, sizeof n->T);
    memcpy(n->T_odo, k->T_wc, sizeof n->T_odo);
    if ((c->st = sooc__slam_decode(n, k->feat, k->feat_bytes, k->depth, k->depth_bytes))) {
        c->s->n_nodes--;
        return 1;
    }
    if (k->id >= c->s->next_id) c->s->next_id = k->id + 1;
    return 0;
}

static int node_index(const sooc_slam *s, int64_t id) {
    for (int i = s->n_nodes - 1; i >= 0; i--)
        if (s->nodes[i].id == id) return i;
    return -1;
}

static int load_edge(const sooc_slamdb_edge *e, void *user) {
    load_ctx *c = user;
    int a = node_index(c->s, e->a), b = node_index(c->s, e->b);
    if (a < 0 || b < 0) {
        c->st = sooc_seterr(SOOC_EFORMAT, "slam: stored edge %lld-%lld names a missing keyframe", (long long)e->a,
                            (long long)e->b);
        return 1;
    }
    sooc_status st = grow_i((void **)&c->s->edges, &c->s->cap_edges, c->s->n_edges + 1, sizeof(sooc_slam_edge));
    if (st) {
        c->st = st;
        return 1;
    }
    sooc_slam_edge *d = &c->s->edges[c->s->n_edges++];
    d->a = a;
    d->b = b;
    d->kind = e->kind;
    memcpy(d->T_ab, e->T_ab, sizeof d->T_ab);
    d->w_t = e->w_t;
    d->w_r = e->w_r;
    return 0;
}

sooc_status sooc_slam_create(sooc_slam **out, const sooc_slam_params *p, sooc_mapstore *store) {
    *out = NULL;
    sooc_slam_params d;
    if (!p) {
        sooc_slam_params_default(&d);
        p = &d;
    }
    if (p->odom.variant == SOOC_ODOM_ICP)
        return sooc_seterr(SOOC_EINVAL, "slam: the icp odometry variant has no grey image for features");
    if (p->n_features < 50 || p->n_features > 10000 || p->min_inliers < 6 || p->min_matches < p->min_inliers ||
        p->max_candidates < 1 || p->recent_window < 0 || !(p->reproj_px > 0) || !(p->min_overlap >= 0 && p->min_overlap <= 1) || p->depth_w < 16 || p->depth_h < 12 ||
        !(p->sigma_odom_m > 0 && p->sigma_odom_rad > 0 && p->sigma_loop_m > 0 && p->sigma_loop_rad > 0) ||
        p->pgo_iterations < 1)
        return sooc_seterr(SOOC_EINVAL, "slam: parameters out of range");
#if !SOOC_HAVE_OPENCV
    (void)store;
    return sooc_seterr(SOOC_EUNSUPPORTED, "slam: sooc3d was built without OpenCV");
#else
    if (p->loop_closure && !sooc_slsh_have_ceres())
        return sooc_seterr(SOOC_EUNSUPPORTED, "slam: loop closure needs Ceres (libceres-dev); turn it off or install it");
    sooc_slam *s = sooc_calloc(1, sizeof *s);
    if (!s) return sooc_seterr(SOOC_ENOMEM, "slam: out of memory");
    s->p = *p;
    s->store = store;
    s->cur_node = s->last_node = -1;
    sooc_se3_identity(s->T_init);
    size_t cap = (size_t)p->n_features;
    s->pairs = sooc_malloc(sizeof(int) * 2 * cap);
    s->obj = sooc_malloc(sizeof(double) * 3 * cap);
    s->img = sooc_malloc(sizeof(double) * 2 * cap);
    sooc_status st = SOOC_OK;
    if (!s->pairs || !s->obj || !s->img) st = sooc_seterr(SOOC_ENOMEM, "slam: out of memory");
    if (!st && store) {
        int64_t nk, ne;
        int32_t max_run;
        st = sooc_mapstore_slam_count(store, &nk, &ne, &max_run);
        s->run = max_run + 1;
        load_ctx c = {s, SOOC_OK};
        if (!st) st = sooc_mapstore_slam_foreach_keyframe(store, load_kf, &c);
        if (!st) st = c.st;
        if (!st) st = sooc_mapstore_slam_foreach_edge(store, load_edge, &c);
        if (!st) st = c.st;
        s->st.stored_keyframes = s->n_nodes;
    }
    if (st) {
        sooc_slam_destroy(s);
        return st;
    }
    s->lost = p->relocalise && s->n_nodes > 0;
    *out = s;
    return SOOC_OK;
#endif
}

void sooc_slam_destroy(sooc_slam *s) {
    if (!s) return;
    for (int i = 0; i < s->n_nodes; i++) sooc__slam_node_free(&s->nodes[i]);
    sooc_free(s->nodes);
    sooc_free(s->edges);
    sooc_free(s->frames);
    sooc_free(s->gray);
    sooc_free(s->depth);
    sooc_free(s->pairs);
    sooc_free(s->obj);
    sooc_free(s->img);
    sooc_free(s->changes);
    sooc_free(s->pend);
#if SOOC_HAVE_OPENCV
    sooc_slsh_icp_destroy(s->icp);
#endif
    sooc_odom_destroy(s->odo);
    sooc_free(s);
}

void sooc_slam_set_initial_pose(sooc_slam *s, const double T_wc[16]) { memcpy(s->T_init, T_wc, sizeof s->T_init); }

void sooc_slam_get_stats(const sooc_slam *s, sooc_slam_stats *st) {
    *st = s->st;
    st->keyframes = s->n_nodes;
}

int64_t sooc_slam_keyframe_count(const sooc_slam *s) { return s->n_nodes; }

uint64_t sooc_slam_graph_version(const sooc_slam *s) { return s->graph_version; }

sooc_status sooc_slam_last_changes(const sooc_slam *s, sooc_slam_kf_change *out, size_t cap, size_t *n) {
    *n = s->n_changes;
    if (out) memcpy(out, s->changes, (cap < s->n_changes ? cap : s->n_changes) * sizeof *out);
    return SOOC_OK;
}

sooc_status sooc_slam_keyframe(const sooc_slam *s, int64_t i, int64_t *id, int32_t *run, int64_t *frame,
                               double T_wc[16]) {
    if (i < 0 || i >= s->n_nodes) return sooc_seterr(SOOC_EINVAL, "slam: keyframe %lld out of range", (long long)i);
    const sooc_slam_node *n = &s->nodes[i];
    if (id) *id = n->id;
    if (run) *run = n->run;
    if (frame) *frame = n->frame;
    if (T_wc) memcpy(T_wc, n->T, sizeof n->T);
    return SOOC_OK;
}

static void frame_pose(const sooc_slam *s, const sooc_slam_frame *f, double T[16]) {
    sooc_se3_mul(T, s->nodes[f->node].T, f->T_rel);
}

sooc_status sooc_slam_trajectory(const sooc_slam *s, sooc_traj *out) {
    out->n = 0;
    for (int64_t i = 0; i < s->n_frames; i++) {
        double T[16];
        frame_pose(s, &s->frames[i], T);
        sooc_status st = sooc_traj_push(out, (double)s->frames[i].t_ns * 1e-9, T);
        if (st) return st;
    }
    return SOOC_OK;
}

int64_t sooc_slam_trajectory_frame(const sooc_slam *s, int64_t i) {
    return i >= 0 && i < s->n_frames ? s->frames[i].index : -1;
}

sooc_status sooc_slam_verify_pair(sooc_slam *s, int64_t a, int64_t b, int *accepted, double T_b_a[16],
                                  int *inliers) {
    if (a < 0 || b < 0 || a >= s->n_nodes || b >= s->n_nodes)
        return sooc_seterr(SOOC_EINVAL, "slam: keyframe pair %lld, %lld out of range", (long long)a, (long long)b);
    return sooc__slam_verify(s, &s->nodes[a], &s->nodes[b], accepted, T_b_a, inliers);
}

/* ------------------------------------------------------------ the graph */

static sooc_status store_node(sooc_slam *s, const sooc_slam_node *n) {
    if (!s->store) return SOOC_OK;
    void *fb = NULL, *db = NULL;
    size_t fn = 0, dn = 0;
    sooc_status st = sooc__slam_encode(n, &fb, &fn, &db, &dn);
    if (st) return st;
    sooc_slamdb_kf k = {.id = n->id, .run = n->run, .frame = n->frame, .t_ns = n->t_ns,
                        .feat = fb, .feat_bytes = fn, .depth = db, .depth_bytes = dn};
    memcpy(k.T_wc, n->T, sizeof k.T_wc);
    st = sooc_mapstore_slam_put_keyframe(s->store, &k);
    sooc_free(fb);
    sooc_free(db);
    return st;
}

static sooc_status optimise(sooc_slam *s) {
#if !SOOC_HAVE_OPENCV
    (void)s;
    return SOOC_OK;
#else
    double t0 = sooc_seconds();
    int nn = s->n_nodes, ne = s->n_edges;
    double *T = sooc_malloc(sizeof(double) * 16 * (size_t)nn);
    double *Tij = sooc_malloc(sizeof(double) * 16 * (size_t)(ne ? ne : 1));
    double *w = sooc_malloc(sizeof(double) * 2 * (size_t)(ne ? ne : 1));
    int *ij = sooc_malloc(sizeof(int) * 2 * (size_t)(ne ? ne : 1));
    uint8_t *fixed = sooc_calloc((size_t)nn, 1), *robust = sooc_calloc((size_t)(ne ? ne : 1), 1);
    int64_t *ids = sooc_malloc(sizeof(int64_t) * (size_t)nn);
    sooc_status st = SOOC_OK;
    if (!T || !Tij || !w || !ij || !fixed || !robust || !ids) {
        st = sooc_seterr(SOOC_ENOMEM, "slam: out of memory (pose graph)");
        goto done;
    }
    for (int i = 0; i < nn; i++) {
        memcpy(T + 16 * (size_t)i, s->nodes[i].T, sizeof s->nodes[i].T);
        ids[i] = s->nodes[i].id;
    }
    fixed[0] = 1;
    for (int e = 0; e < ne; e++) {
        const sooc_slam_edge *E = &s->edges[e];
        ij[2 * e] = E->a;
        ij[2 * e + 1] = E->b;
        memcpy(Tij + 16 * (size_t)e, E->T_ab, sizeof E->T_ab);
        w[2 * e] = E->w_t;
        w[2 * e + 1] = E->w_r;
        robust[e] = E->kind == 1 || E->kind == 2 || E->kind == 4;
    }
    char err[512] = "";
    int iters = 0;
    if (sooc_slsh_pgo(nn, T, fixed, ne, ij, Tij, w, robust, s->p.pgo_iterations, &s->st.last_pgo_cost0,
                      &s->st.last_pgo_cost1, &iters, err, sizeof err)) {
        st = sooc_seterr(SOOC_ERR, "slam: %s", err);
        goto done;
    }
    /* this run's keyframes before and after (nodes are in time order within a run) */
    s->n_changes = 0;
    for (int i = 0; i < nn; i++)
        if (s->nodes[i].run == s->run) s->n_changes++;
    if (s->n_changes > s->cap_changes) {
        sooc_free(s->changes);
        s->changes = sooc_malloc(s->n_changes * sizeof *s->changes);
        s->cap_changes = s->changes ? s->n_changes : 0;
        if (!s->changes) {
            s->n_changes = 0;
            st = sooc_seterr(SOOC_ENOMEM, "slam: out of memory (pose changes)");
            goto done;
        }
    }
    size_t k = 0;
    for (int i = 0; i < nn; i++) {
        if (s->nodes[i].run != s->run) continue;
        sooc_slam_kf_change *c = &s->changes[k++];
        c->t_ns = s->nodes[i].t_ns;
        memcpy(c->T_before, s->nodes[i].T, sizeof c->T_before);
        memcpy(c->T_after, T + 16 * (size_t)i, sizeof c->T_after);
    }
    for (int i = 0; i < nn; i++) memcpy(s->nodes[i].T, T + 16 * (size_t)i, sizeof s->nodes[i].T);
    s->st.optimisations++;
    s->graph_version++;
    if (s->store) st = sooc_mapstore_slam_set_poses(s->store, ids, T, (size_t)nn);
done:
    sooc_free(T);
    sooc_free(Tij);
    sooc_free(w);
    sooc_free(ij);
    sooc_free(fixed);
    sooc_free(robust);
    sooc_free(ids);
    s->st.ms_pgo += (sooc_seconds() - t0) * 1e3;
    return st;
#endif
}

/* the best max_candidates nodes for query q among nodes [0, limit), by
 * descriptor matches; cand[] gets their indices, returns their number */
static int near_enough(const sooc_slam *s, const sooc_slam_node *q, const sooc_slam_node *b) {
    if (s->p.loop_max_dist_m <= 0) return 1;
    double dx = q->T[3] - b->T[3], dy = q->T[7] - b->T[7], dz = q->T[11] - b->T[11];
    if (dx * dx + dy * dy + dz * dz > s->p.loop_max_dist_m * s->p.loop_max_dist_m) return 0;
    /* viewing directions (camera z axes) within loop_max_angle_deg */
    double c = q->T[2] * b->T[2] + q->T[6] * b->T[6] + q->T[10] * b->T[10];
    return c >= cos(s->p.loop_max_angle_deg * M_PI / 180.0);
}

/* near: only nodes whose pose lies near q's (loop search; relocalisation
 * has no pose and tries every node) */
static int find_candidates(sooc_slam *s, const sooc_slam_node *q, int limit, int near, int *cand) {
    int nc = 0, k = s->p.max_candidates;
    int score[16];
    if (k > 16) k = 16;
    for (int i = 0; i < limit; i++) {
        if (near && !near_enough(s, q, &s->nodes[i])) continue;
        int m = sooc__slam_match(q, &s->nodes[i], NULL, s->p.n_features);
        if (m < s->p.min_matches) continue;
        int pos = nc < k ? nc++ : k;
        if (pos == k && m <= score[k - 1]) continue;
        if (pos == k) pos = k - 1;
        while (pos > 0 && score[pos - 1] < m) {
            score[pos] = score[pos - 1];
            cand[pos] = cand[pos - 1];
            pos--;
        }
        score[pos] = m;
        cand[pos] = i;
    }
    return nc;
}

/* loop search for the newest node c: its candidates join the queue of
 * pairs to verify (verify_pending) */
static sooc_status find_loops(sooc_slam *s, int c) {
    double t0 = sooc_seconds();
    int limit = c - s->p.recent_window;
    /* nodes of this run's current segment within the window are skipped;
     * stored nodes and older segments are all candidates */
    if (limit <= 0) return SOOC_OK;
    int cand[32];
    int nc = find_candidates(s, &s->nodes[c], limit, 1, cand);
    int nloop = nc;
    /* local edges: the recent keyframes of this segment besides the previous one */
    for (int i = c - 2; s->p.local_edges && i >= 0 && i >= c - s->p.recent_window && nc < 32; i--)
        if (s->nodes[i].segment == s->nodes[c].segment) cand[nc++] = i;
    sooc_status st = grow_i((void **)&s->pend, &s->cap_pend, s->n_pend + nc, sizeof *s->pend);
    for (int k = 0; k < nc && !st; k++) s->pend[s->n_pend++] = (sooc_slam_pair){c, cand[k], k >= nloop};
    s->st.ms_loop += (sooc_seconds() - t0) * 1e3;
    return st;
}

/* verify up to budget queued pairs (budget <= 0: all); once the queue is
 * empty, the edges they added are optimised in one go */
static sooc_status verify_pending(sooc_slam *s, int budget, int *closed) {
    *closed = 0;
    double t0 = sooc_seconds();
    sooc_status st = SOOC_OK;
    int done = 0;
    while (done < s->n_pend && (budget <= 0 || done < budget) && !st) {
        const sooc_slam_pair e = s->pend[done++];
        int local = e.local, ok = 0, inl = 0;
        if (!local) s->st.loop_candidates++;
        double T_b_c[16];
        if ((st = sooc__slam_verify(s, &s->nodes[e.q], &s->nodes[e.b], &ok, T_b_c, &inl))) break;
        if (!ok) {
            if (!local) s->st.loop_rejected++;
            continue;
        }
        st = add_edge(s, e.b, e.q, local ? 4 : 1, T_b_c, 1.0 / s->p.sigma_loop_m, 1.0 / s->p.sigma_loop_rad);
        if (!st) {
            if (local) s->pend_local++;
            else s->pend_loops++;
        }
    }
    s->n_pend -= done;
    if (done && s->n_pend) memmove(s->pend, s->pend + done, sizeof *s->pend * (size_t)s->n_pend);
    s->st.ms_loop += (sooc_seconds() - t0) * 1e3;
    if (!st && !s->n_pend && (s->pend_loops || s->pend_local)) {
        s->st.loops += s->pend_loops;
        s->st.local_edges += s->pend_local;
        *closed = s->pend_loops > 0;
        s->pend_loops = s->pend_local = 0;
        st = optimise(s);
    }
    return st;
}

sooc_status sooc_slam_flush(sooc_slam *s, int *loop_closed) {
    int closed = 0;
    sooc_status st = verify_pending(s, 0, &closed);   /* nothing to do on an empty queue */
    if (loop_closed) *loop_closed = closed;
    return st;
}

int sooc_slam_pending(const sooc_slam *s) { return s->n_pend; }

/* a new node from the odometry's current frame */
static sooc_status new_node(sooc_slam *s, const sooc_frame *f, const double T_w[16], const double T_odo[16],
                            int *index) {
    double t0 = sooc_seconds();
    sooc_slam_node *n;
    sooc_status st = add_node(s, &n);
    if (st) return st;
    n->id = s->next_id++;
    n->run = s->run;
    n->frame = f->index;
    n->t_ns = f->t_ns;
    n->segment = s->segment;
    memcpy(n->T, T_w, sizeof n->T);
    memcpy(n->T_odo, T_odo, sizeof n->T_odo);
    if ((st = sooc__slam_extract(s, n))) {
        s->n_nodes--;
        return st;
    }
    *index = s->n_nodes - 1;
    s->st.ms_features += (sooc_seconds() - t0) * 1e3;
    return SOOC_OK;
}

static void drop_last_node(sooc_slam *s) {
    sooc__slam_node_free(&s->nodes[--s->n_nodes]);
    s->next_id--;
}

/* store node c and its edge from a (a < 0: none) in one transaction */
static sooc_status commit_node(sooc_slam *s, int c, int a, int kind, const double T_ac[16], double wt, double wr) {
    sooc_status st = SOOC_OK;
    if (s->store && (st = sooc_mapstore_begin(s->store))) return st;
    st = store_node(s, &s->nodes[c]);
    if (!st && a >= 0) st = add_edge(s, a, c, kind, T_ac, wt, wr);
    if (s->store) {
        if (st) sooc_mapstore_rollback(s->store);
        else st = sooc_mapstore_commit(s->store);
    }
    return st;
}

static sooc_status push_frame(sooc_slam *s, const sooc_frame *f, int node, const double T_rel[16]) {
    sooc_status st = grow((void **)&s->frames, &s->cap_frames, s->n_frames + 1, sizeof(sooc_slam_frame));
    if (st) return st;
    sooc_slam_frame *fr = &s->frames[s->n_frames++];
    fr->index = f->index;
    fr->t_ns = f->t_ns;
    fr->node = node;
    memcpy(fr->T_rel, T_rel, sizeof fr->T_rel);
    return SOOC_OK;
}

/* start an odometry segment on this frame: a new map, a relocalisation or
 * a re-anchor at the last pose */
static sooc_status start_segment(sooc_slam *s, const sooc_frame *f, sooc_slam_result *r) {
    sooc_odom_destroy(s->odo);
    s->odo = NULL;
    sooc_status st = sooc_odom_create(&s->odo, &s->p.odom);
    if (st) return st;
    sooc_odom_result o;
    if ((st = sooc_odom_track(s->odo, f, &o))) return st;
    s->segment++;
    double I[16];
    sooc_se3_identity(I);
    int c = -1;
    if (s->lost) {
        double t0 = sooc_seconds();
        s->st.reloc_attempts++;
        if ((st = new_node(s, f, I, I, &c))) return st;
        int cand[16], b = -1, ok = 0, inl = 0;
        double T_b_q[16];
        int nc = find_candidates(s, &s->nodes[c], c, 0, cand);
        for (int k = 0; k < nc && !ok; k++) {
            if ((st = sooc__slam_verify(s, &s->nodes[c], &s->nodes[cand[k]], &ok, T_b_q, &inl))) break;
            if (ok) b = cand[k];
        }
        s->st.ms_reloc += (sooc_seconds() - t0) * 1e3;
        if (st || !ok) {
            drop_last_node(s);
            sooc_odom_destroy(s->odo);
            s->odo = NULL;
            if (!st) {
                s->st.lost++;
                r->state = SOOC_SLAM_LOST;
            }
            return st;
        }
        sooc_se3_mul(s->nodes[c].T, s->nodes[b].T, T_b_q);
        if ((st = commit_node(s, c, b, 2, T_b_q, 1.0 / s->p.sigma_loop_m, 1.0 / s->p.sigma_loop_rad))) return st;
        s->lost = 0;
        s->st.relocalised++;
        r->state = SOOC_SLAM_RELOCALISED;
    } else if (s->reanchor && s->last_node >= 0) {
        /* the pose is uncertain: a weak edge to the last node; this frame is not tracked */
        if ((st = new_node(s, f, s->T_last, I, &c))) return st;
        double inv[16], T_ac[16];
        sooc_se3_inverse(inv, s->nodes[s->last_node].T);
        sooc_se3_mul(T_ac, inv, s->T_last);
        if ((st = commit_node(s, c, s->last_node, 3, T_ac, 1.0, 1.0))) return st;
        s->reanchor = 0;
        s->cur_node = s->last_node = c;
        r->new_keyframe = 1;
        r->keyframe_id = s->nodes[c].id;
        s->st.failed++;
        return SOOC_OK;
    } else {
        if ((st = new_node(s, f, s->T_init, I, &c))) return st;
        if ((st = commit_node(s, c, -1, 0, I, 1, 1))) return st;
        s->reanchor = 0;
        r->state = SOOC_SLAM_FIRST;
    }
    s->cur_node = s->last_node = c;
    r->new_keyframe = 1;
    r->keyframe_id = s->nodes[c].id;
    memcpy(r->T_wc, s->nodes[c].T, sizeof r->T_wc);
    memcpy(s->T_last, r->T_wc, sizeof s->T_last);
    s->st.tracked++;
    return push_frame(s, f, c, I);
}

sooc_status sooc_slam_track(sooc_slam *s, const sooc_frame *f, sooc_slam_result *r) {
    memset(r, 0, sizeof *r);
    r->state = SOOC_SLAM_FAILED;
    r->keyframe_id = -1;
    sooc_se3_identity(r->T_wc);
    double t0 = sooc_seconds();
    s->st.frames++;
    sooc_status st = SOOC_OK;
    if (s->lost || s->reanchor || !s->odo) {
        st = start_segment(s, f, r);
        goto done;
    }
    double t1 = sooc_seconds();
    sooc_odom_result o;
    st = sooc_odom_track(s->odo, f, &o);
    s->st.ms_track += (sooc_seconds() - t1) * 1e3;
    if (st) goto done;
    if (o.state == SOOC_ODOM_FAILED || o.state == SOOC_ODOM_REANCHORED) {
        s->st.failed++;
        if (o.state == SOOC_ODOM_REANCHORED) {
            if (s->p.relocalise) s->lost = 1;
            else s->reanchor = 1;
        }
        goto done;
    }
    int cur = s->cur_node;
    if (o.new_keyframe) {
        const sooc_slam_node *pn = &s->nodes[cur];
        double inv[16], rel[16], T_w[16];
        sooc_se3_inverse(inv, pn->T_odo);
        sooc_se3_mul(rel, inv, o.T_wc);
        sooc_se3_mul(T_w, pn->T, rel);
        int c;
        if ((st = new_node(s, f, T_w, o.T_wc, &c))) goto done;
        if ((st = commit_node(s, c, cur, 0, rel, 1.0 / s->p.sigma_odom_m, 1.0 / s->p.sigma_odom_rad))) goto done;
        s->cur_node = s->last_node = cur = c;
        r->new_keyframe = 1;
        if (s->p.loop_closure && (st = find_loops(s, c))) goto done;
        /* the keyframe's frame pays for features and the search; its
         * candidates are verified on the frames after it */
        if (s->p.loop_verify_per_frame <= 0 && (st = verify_pending(s, 0, &r->loop_closed))) goto done;
    } else if (s->n_pend && (st = verify_pending(s, s->p.loop_verify_per_frame, &r->loop_closed))) {
        goto done;
    }
    double inv[16], rel[16];
    sooc_se3_inverse(inv, s->nodes[cur].T_odo);
    sooc_se3_mul(rel, inv, o.T_wc);
    if ((st = push_frame(s, f, cur, rel))) goto done;
    frame_pose(s, &s->frames[s->n_frames - 1], r->T_wc);
    memcpy(s->T_last, r->T_wc, sizeof s->T_last);
    r->state = SOOC_SLAM_TRACKED;
    r->keyframe_id = s->nodes[cur].id;
    s->st.tracked++;
done:
    r->ms = (sooc_seconds() - t0) * 1e3;
    return st;
}
