/* The node: capture thread -> frame ring -> (mapping thread = caller of
 * sooc_node_run) pose association, keyframe policy, preprocessing,
 * sooc_mapper_update, publisher (shm table batch + SQLite transaction per
 * keyframe) and periodic stats. */
#include "node/node_impl.h"

/* ------------------------------------------------------------- helpers */

void sooc_node_request_stop(sooc_node *n) {
    atomic_store(&n->stop, 1);
    pthread_mutex_lock(&n->sensor_mu);
    if (n->sensor) sooc_sensor_interrupt(n->sensor);
    pthread_mutex_unlock(&n->sensor_mu);
    if (n->ring) sooc_frame_ring_close(n->ring);
}

/* ------------------------------------------------ driver / pose adapters */

/* ctx = the node: a reconnect swaps its sensor (capture thread only) */
static sooc_status drv_start(void *ctx) { return sooc_sensor_start(((sooc_node *)ctx)->sensor); }
static sooc_frame_fault drv_frame_fault(void *ctx) { return sooc_sensor_frame_fault(((sooc_node *)ctx)->sensor); }
static sooc_status drv_read(void *ctx, sooc_frame *f, int t) { return sooc_sensor_read(((sooc_node *)ctx)->sensor, f, t); }
static void drv_stop(void *ctx) {
    sooc_node *n = ctx;
    if (n->sensor) sooc_sensor_stop(n->sensor);
}
/* A live sensor that failed: closed and opened again with the same parameters. */
static sooc_status drv_reopen(void *ctx) {
    sooc_node *n = ctx;
    sooc_sensor *fresh = NULL;
    pthread_mutex_lock(&n->sensor_mu);
    sooc_sensor_close(n->sensor);   /* stops the stream */
    n->sensor = NULL;
    pthread_mutex_unlock(&n->sensor_mu);
    sooc_status st = sooc_sensor_open(&fresh, n->cfg.driver, &n->sensor_params);
    if (!st && (st = sooc_sensor_start(fresh))) {
        sooc_sensor_close(fresh);
        fresh = NULL;
    }
    pthread_mutex_lock(&n->sensor_mu);
    n->sensor = fresh;
    if (fresh && atomic_load(&n->stop)) sooc_sensor_interrupt(fresh);
    pthread_mutex_unlock(&n->sensor_mu);
    return st;
}
static void drv_close(void *ctx) { (void)ctx; /* closed in destroy (after the thread is joined) */ }

static sooc_status pose_lookup_file(void *ctx, int64_t t, int64_t tol, double T[16]) {
    return sooc_pose_lookup(ctx, t, tol, T);
}
static sooc_status pose_lookup_socket(void *ctx, int64_t t, int64_t tol, double T[16]) {
    int wait_ms = (int)(tol / 1000000) + 50;
    return sooc_pose_wait_lookup(ctx, t, tol, wait_ms, T);
}
static void pose_close(void *ctx) { sooc_pose_close(ctx); }

/* launch key -> driver.h sooc_sensor_params_set key */
static const char *map_key(const char *driver, const char *key, const char **value) {
    if (!strcmp(key, "path") || !strcmp(key, "depth_device") || !strcmp(key, "index") ||
        !strcmp(key, "camera"))
        return "uri";
    if (!strcmp(key, "color_device")) return "uri2";
    if (!strcmp(key, "depth_mode")) return "depth_format";
    if (!strcmp(key, "speed")) {
        if (!strcmp(*value, "realtime")) *value = "1";
        else if (!strcmp(*value, "fast")) *value = "0";
        return "speed";
    }
    if (!strcmp(key, "format") && !strcmp(*value, "auto")) return NULL;   /* leave NULL = auto */
    (void)driver;
    return key;
}

static sooc_status open_sensor(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    sooc_sensor_params sp;
    sooc_sensor_params_default(&sp);
    for (int i = 0; i < c->n_params; i++) {
        const char *v = c->params[i].value;
        const char *k = map_key(c->driver, c->params[i].key, &v);
        if (!k) continue;
        sooc_status st = sooc_sensor_params_set(&sp, k, v);
        if (st)
            return sooc_adderr(st, "%s:%d: sensor.%s", c->path, c->params[i].line, c->params[i].key);
    }
    if (c->pose_kind == SOOC_NODE_POSE_TF) {   /* the log's TF gives the frames their poses */
        sp.pose_parent = c->pose_parent;
        sp.pose_child = c->pose_child[0] ? c->pose_child : NULL;
    }
    sp.depth_min = (float)c->min_depth_m;
    sp.depth_max = (float)c->max_depth_m;
    if (n->have_calib && n->calib.depth_scale > 0 && !sooc_node_param_get(c, "depth_scale"))
        sp.depth_scale = n->calib.depth_scale;
    /* the calib's depth decoding keys, like depth_scale (replay; frame.h) */
    if (n->have_calib && n->calib.depth_shift >= 0 && !sooc_node_param_get(c, "depth_shift"))
        sp.depth_shift = n->calib.depth_shift;
    if (n->have_calib && n->calib.depth_invalid >= 0 && !sooc_node_param_get(c, "depth_invalid"))
        sp.depth_invalid = n->calib.depth_invalid;
    sp.v4l2_ops = n->opt.v4l2_ops;
    n->sensor_params = sp;   /* its strings live in the node's config */
    sooc_status st = sooc_sensor_open(&n->sensor, c->driver, &sp);
    if (st) return sooc_adderr(st, "%s: sensor (driver %s)", c->path, c->driver);
    n->src.ctx = n;
    /* a live device that fails is reopened; a recording's failure is its own */
    if (strcmp(c->driver, "replay") && strcmp(c->driver, "rosbag") && strcmp(c->driver, "mcap"))
        n->src.reopen = drv_reopen;
    n->src.start = drv_start;
    n->src.read = drv_read;
    n->src.stop = drv_stop;
    n->src.close = drv_close;
    n->src.frame_fault = drv_frame_fault;
    n->have_src = 1;
    sooc_sensor_info si;
    sooc_sensor_get_info(n->sensor, &si);
    if (si.n_frames > 0) n->skip_limit = (uint64_t)si.n_frames;
    return SOOC_OK;
}

static sooc_status open_pose(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    if (c->pose_kind == SOOC_NODE_POSE_SENSOR || c->pose_kind == SOOC_NODE_POSE_ODOMETRY ||
        c->pose_kind == SOOC_NODE_POSE_TF)
        return SOOC_OK;
    sooc_pose_params pp;
    sooc_pose_params_default(&pp);
    if (n->have_T_eff) {
        pp.has_hand_eye = 1;
        memcpy(pp.T_effector_camera, n->T_eff_cam, sizeof pp.T_effector_camera);
    } else if (c->pose_is_effector) {
        return sooc_seterr(SOOC_EINVAL, "%s: pose.frame: effector, but calib %s has no T_effector_camera",
                           c->path, c->calib_path);
    }
    pp.text_kind = c->pose_is_effector ? SOOC_POSE_EFFECTOR : SOOC_POSE_CAMERA;
    sooc_status st;
    if (c->pose_kind == SOOC_NODE_POSE_FILE) {
        st = sooc_pose_open_file(&n->psrc, c->pose_path, &pp);
        n->pose.lookup = pose_lookup_file;
    } else {
        st = sooc_pose_open_socket(&n->psrc, c->pose_path, &pp);
        n->pose.lookup = pose_lookup_socket;
    }
    if (st) return sooc_adderr(st, "%s: pose.path", c->path);
    n->pose.ctx = n->psrc;
    n->pose.close = pose_close;
    n->have_pose = 1;
    return SOOC_OK;
}

/* ---------------------------------------------------------------- create */

static sooc_status load_calib(sooc_node *n) {
    if (!n->cfg.calib_path[0]) return SOOC_OK;
    sooc_status st = sooc_calib_load(n->cfg.calib_path, &n->calib);
    if (st) return sooc_adderr(st, "%s: calib", n->cfg.path);
    n->have_calib = 1;
    n->Kc = n->calib.K;
    n->calib_registered = n->calib.depth_registered;
    if (n->calib.has_T_color_depth) {
        n->have_T_cd = 1;
        memcpy(n->T_cd, n->calib.T_color_depth, sizeof n->T_cd);
    }
    if (n->calib.has_T_effector_camera) {
        n->have_T_eff = 1;
        memcpy(n->T_eff_cam, n->calib.T_effector_camera, sizeof n->T_eff_cam);
    }
    if (n->calib_registered == 0 && !n->have_T_cd)
        return sooc_seterr(SOOC_EINVAL, "%s: depth_registered is false but T_color_depth is missing",
                           n->cfg.calib_path);
    return SOOC_OK;
}


/* ---------------------------------------------------------- world frame */

static void support_free(sooc_node *n);

static void set_world(sooc_node *n, const double T[16]) {
    pthread_mutex_lock(&n->mu);   /* stats_refresh reads T_world_src on other threads */
    memcpy(n->T_world_src, T, 16 * sizeof(double));
    n->st.floor_estimated = n->cfg.floor_mode == SOOC_NODE_FLOOR_ESTIMATE;
    pthread_mutex_unlock(&n->mu);
    n->world_ready = 1;
}


/* The map's world frame at start-up. A database that holds one (written when
 * the frame was first estimated or given) fixes it on resume: the estimate
 * is skipped, and a given world.up/floor that disagrees is overridden with a
 * warning (the stored entries live in the stored frame). Otherwise a given
 * frame is stored now; an estimated one when it is made. */
static sooc_status world_from_store(sooc_node *n, int resumed) {
    const sooc_node_config *c = &n->cfg;
    if (n->sg) {   /* a store, or one to be created later (store_guard.h) */
        sooc_map_frame mf;
        int found = 0;
        sooc_status st = n->store ? sooc_mapstore_frame_get(n->store, &mf, &found) : SOOC_OK;
        if (st) return sooc_adderr(st, "%s: map.db", c->path);
        if (found && resumed) {
            if (n->world_ready) {
                double d = 0;
                for (int i = 0; i < 12; i++) d = fmax(d, fabs(mf.T_world_src[i] - n->T_world_src[i]));
                if (d > 1e-3)
                    sooc_log(SOOC_LOG_WARN,
                             "%s: world.up/floor differ from the world frame stored in %s (max element difference "
                             "%.3g); using the stored one, which the resumed map was built in",
                             c->path, c->map_db, d);
            }
            set_world(n, mf.T_world_src);
            sooc_log(SOOC_LOG_INFO,
                     "node: world frame from %s: up (%.3f %.3f %.3f) from %s, camera %.2f m above the support plane "
                     "when estimated",
                     c->map_db, mf.up_src[0], mf.up_src[1], mf.up_src[2],
                     mf.up_source >= 0 ? sooc_up_source_name((sooc_up_source)mf.up_source) : "world.floor (given)",
                     mf.cam_height_m);
            support_free(n);
            return SOOC_OK;
        }
        if (n->world_ready && !found) {   /* world.floor given: store it */
            memset(&mf, 0, sizeof mf);
            memcpy(mf.T_world_src, n->T_world_src, sizeof mf.T_world_src);
            memcpy(mf.up_src, c->up, sizeof mf.up_src);
            memcpy(mf.plane_src, c->up, 3 * sizeof(double));
            mf.plane_src[3] = -c->floor_height;
            mf.up_source = -1;
            return sooc__node_store_world(n, &mf);
        }
    }
    return SOOC_OK;
}

/* Buffers for world.floor: estimate, and the gravity hint. */
static sooc_status support_init(sooc_node *n) {
    const sooc_node_config *c = &n->cfg;
    n->cap_sup = sooc__node_support_cap(c);
    n->sup_f = sooc_calloc((size_t)n->cap_sup, sizeof *n->sup_f);
    n->sup_T = sooc_malloc(16 * sizeof(double) * (size_t)n->cap_sup);
    n->sup_tcap = sooc_malloc(sizeof(int64_t) * (size_t)n->cap_sup);
    if (!n->sup_f || !n->sup_T || !n->sup_tcap) return sooc_seterr(SOOC_ENOMEM, "node: out of memory");
    char path[SOOC_NODE_PATH_MAX + 32];
    const char *rp = sooc_node_param_get(c, "path");
    int auto_g = !c->gravity_path[0] || !strcmp(c->gravity_path, "auto");
    if (!strcmp(c->gravity_path, "none")) return SOOC_OK;
    if (auto_g) {
        if (strcmp(c->driver, "replay") || !rp) return SOOC_OK;
        /* the file is in the recording's pose frame, not the odometry's */
        if (c->pose_kind == SOOC_NODE_POSE_ODOMETRY) return SOOC_OK;
        snprintf(path, sizeof path, "%s/gravity-direction.txt", rp);
        if (!sooc_file_exists(path)) return SOOC_OK;
    } else {
        snprintf(path, sizeof path, "%s", c->gravity_path);
    }
    sooc_status st = sooc_support_read_gravity(path, n->gravity);
    if (st) return sooc_adderr(st, "%s: world.gravity", c->path);
    n->has_gravity = 1;
    sooc_log(SOOC_LOG_INFO, "node: gravity (%.4f %.4f %.4f) from %s", n->gravity[0], n->gravity[1], n->gravity[2],
             path);
    return SOOC_OK;
}

static void support_free(sooc_node *n) {
    for (int i = 0; i < n->cap_sup; i++) sooc_frame_free(&n->sup_f[i]);
    sooc_free(n->sup_f);
    sooc_free(n->sup_T);
    sooc_free(n->sup_tcap);
    n->sup_f = NULL;
    n->sup_T = NULL;
    n->sup_tcap = NULL;
    n->n_sup = n->cap_sup = 0;
}

sooc_status sooc_node_create(sooc_node **out, const sooc_node_config *c, const sooc_node_options *o) {
    *out = NULL;
    sooc_node *n = sooc_calloc(1, sizeof *n);
    if (!n) return SOOC_ENOMEM;
    n->cfg = *c;
    if (o) n->opt = *o;
    pthread_mutex_init(&n->mu, NULL);
    pthread_mutex_init(&n->sensor_mu, NULL);
    atomic_init(&n->stop, 0);
    n->calib_registered = -1;
    n->t_start = n->t_last_stats = sooc_seconds();
    sooc_se3_identity(n->T_world_src);
    sooc_kf_policy_init(&n->kf, c->kf_translation_m, c->kf_rotation_deg, c->kf_time_s);
    n->model_id = sooc_crc32(0, c->model_path, strlen(c->model_path));
    sooc_status st = SOOC_OK;

    if (c->floor_mode == SOOC_NODE_FLOOR_GIVEN) {
        sooc_frames_world_from_up(c->up, c->floor_height, n->T_world_src);
        n->world_ready = 1;
    }
    /* model */
    if (n->opt.mapper) {
        n->mapper = n->opt.mapper;
    } else {
        sooc_mapper_params mp;
        sooc_mapper_params_default(&mp);
        mp.model_path = c->model_path;
        mp.iterations = c->iterations;
        mp.seed = c->seed;
        mp.threads = c->threads;
        mp.d_clip = c->clip_m;
        mp.merge_radius = c->merge_m;
        mp.merge_neighbours = 1;   /* revisits refine the mapped entry (docs/cogmap.md "Revisits") */
        mp.latents = c->latents;
        mp.slots = c->slots;
        mp.invalid_depth = c->invalid_depth;
        mp.gate_min_rays = c->gate_min_rays;   /* the creation gate (revisit rule 5): 0 = default */
        mp.gate_ratio = c->gate_ratio;
        mp.gate_part = c->gate_part;
        if (c->model_kind == SOOC_MAPPER_GEOMETRIC) {   /* the geometric map (docs/geometric.md "In the node") */
            mp.kind = SOOC_MAPPER_GEOMETRIC;
            mp.cluster.voxel_m = c->geo_voxel_m, mp.cluster.dist_m = c->geo_join_m;
            mp.cluster.min_height_m = c->geo_min_height_m, mp.cluster.max_extent_m = c->geo_max_extent_m;
            mp.cluster.wall_m = c->geo_wall_m;
            mp.cluster.rest_m = c->geo_rest_m;
            mp.min_presence = c->geo_min_presence;
            mp.cluster.free_ratio = c->geo_free_ratio;
            mp.cluster.max_depth_m = c->max_depth_m < 3.0 ? c->max_depth_m : 3.0;
            if (c->input_width > 0) mp.input_width = c->input_width, mp.input_height = c->input_height;
            if ((st = sooc_mapper_create(&n->mapper, &mp))) {
                sooc_adderr(st, "%s: model.kind geometric", c->path);
                goto fail;
            }
            n->own_mapper = 1;
            /* the map's identity: the clustering that made it (voxel, join, min height, max extent, wall in
             * m; free-space ratio; rest height in m) */
            snprintf(n->model_id_str, sizeof n->model_id_str, "geometric %.4g %.4g %.4g %.4g %.4g %.4g %.4g",
                     mp.cluster.voxel_m, mp.cluster.dist_m, mp.cluster.min_height_m, mp.cluster.max_extent_m,
                     mp.cluster.wall_m, mp.cluster.free_ratio, mp.cluster.rest_m);
        } else {
            if (!c->model_path[0]) {
                st = sooc_seterr(SOOC_EINVAL, "%s: model.path: missing", c->path);
                goto fail;
            }
            if ((st = sooc_mapper_create(&n->mapper, &mp))) {
                sooc_adderr(st, "%s: model.path %s", c->path, c->model_path);
                goto fail;
            }
            n->own_mapper = 1;
            if (c->proposals || c->prop_only) {   /* docs/geometric.md "Proposals for the learnt mapper" */
                sooc_proposal_params pp;
                sooc_proposal_params_default(&pp);
                pp.on = 1;
                if (c->prop_join_m > 0) pp.cluster.dist_m = c->prop_join_m;
                if (c->prop_logit != 0) pp.pres_logit = c->prop_logit;
                if (c->prop_only) pp.rest_logit = -20;
                if ((st = sooc_mapper_set_proposals(n->mapper, &pp))) {
                    sooc_adderr(st, "%s: model.proposals", c->path);
                    goto fail;
                }
            }
            /* entries must stand on support-plane clusters (docs/geometric.md "Geometric support") */
            if (c->geo_support_m > 0 && (st = sooc_mapper_set_support(n->mapper, c->geo_support_m))) {
                sooc_adderr(st, "%s: model.geo_support_m", c->path);
                goto fail;
            }
            sooc_mapper_set_surface_boxes(n->mapper, c->surface_boxes);   /* docs/geometric.md */
            /* the model's identity is its checkpoint's content, not its path */
            if (sooc_file_id(c->model_path, n->model_id_str, sizeof n->model_id_str, &n->model_id)) {
                /* a mapper that does not read model.path as a file (tests): no model check */
                n->model_id_str[0] = 0;
                sooc_log(SOOC_LOG_DEBUG, "%s: model.path %s: %s: map.db model_id not set", c->path, c->model_path,
                         sooc_errmsg());
            }
        }
    }
    sooc_mapper_input_size(n->mapper, &n->tw, &n->th);
    if (c->input_width > 0 && (c->input_width != n->tw || c->input_height != n->th)) {
        st = sooc_seterr(SOOC_EINVAL, "%s: model.width/height: %dx%d, but the model takes %dx%d", c->path,
                         c->input_width, c->input_height, n->tw, n->th);
        goto fail;
    }
    if (n->tw <= 0 || n->th <= 0) {
        st = sooc_seterr(SOOC_EINVAL, "%s: model: input size %dx%d is invalid", c->path, n->tw, n->th);
        goto fail;
    }
    if ((st = load_calib(n))) goto fail;

    /* sources */
    if (n->opt.source) {
        n->src = *n->opt.source;
        n->have_src = 1;
    }
    if (n->opt.pose) {
        n->pose = *n->opt.pose;
        n->have_pose = 1;
    }
    if (!n->have_src && (st = open_sensor(n))) goto fail;
    if (!n->have_pose && (st = open_pose(n))) goto fail;
    if (c->pose_kind == SOOC_NODE_POSE_ODOMETRY && !n->have_pose) {
        sooc_odom_params op;
        sooc_odom_params_default(&op);
        op.variant = (sooc_odom_variant)c->odom_variant;
        op.width = c->odom_width;
        op.height = c->odom_height;
        op.kf_translation_m = c->odom_kf_translation_m;
        op.kf_rotation_deg = c->odom_kf_rotation_deg;
        op.kf_max_frames = c->odom_kf_frames;
        op.max_failures = c->odom_max_failures;
        op.min_depth_m = c->odom_min_depth_m;
        op.max_depth_m = c->odom_max_depth_m;
        op.min_agreement = c->odom_min_agreement;
        if (c->odom_color_fx > 0) {   /* colour not registered to depth (7-Scenes) */
            op.color_K[0] = c->odom_color_fx;
            op.color_K[1] = c->odom_color_fy;
            op.color_K[2] = c->odom_color_cx;
            op.color_K[3] = c->odom_color_cy;
            op.T_color_depth[3] = c->odom_color_tx;
            op.T_color_depth[7] = c->odom_color_ty;
            op.T_color_depth[11] = c->odom_color_tz;
        }
        n->odom_params = op;   /* the tracking thread's, when asked for (tracking.c) */
        if (!sooc__node_tracking_wanted(n) && (st = sooc_odom_create(&n->odom, &op))) {
            sooc_adderr(st, "%s: pose.source: odometry", c->path);
            goto fail;
        }
    } else if (c->pose_kind != SOOC_NODE_POSE_SENSOR && c->pose_kind != SOOC_NODE_POSE_TF && !n->have_pose) {
        st = sooc_seterr(SOOC_EUNSUPPORTED, "%s: pose: no pose source available", c->path);
        goto fail;
    }
    if ((st = sooc_frame_ring_create(&n->ring, c->ring_capacity))) goto fail;
    if (c->view_port) {
        sooc_view_params vp = {c->view_port, c->view_bind};
        if ((st = sooc_view_start(&n->view, &vp))) {
            sooc_adderr(st, "%s: view", c->path);
            goto fail;
        }
    }
    if ((st = sooc__node_record_open(n))) goto fail;
    sooc_frame_ring_set_blocking(n->ring, c->block_when_full);
    if (c->floor_mode == SOOC_NODE_FLOOR_ESTIMATE && (st = support_init(n))) goto fail;

    /* persistent map: resume */
    int resumed = 0;
    if ((st = sooc__node_store_resume(n, &resumed))) goto fail;
    if ((st = world_from_store(n, resumed))) goto fail;
    /* world.floor: estimate and a frame from the store: it was estimated in an earlier run */
    if ((st = sooc__node_floor_watch_init(n, n->world_ready))) goto fail;
    /* what the mapper holds now (resumed, or preloaded by the caller) is republished at start */
    {
        size_t cnt = 0;
        if ((st = sooc_mapper_entries(n->mapper, NULL, 0, &cnt))) goto fail;
        if ((st = sooc__node_grow((void **)&n->prev, &n->cap_prev, cnt + 1, sizeof *n->prev))) goto fail;
        if ((st = sooc_mapper_entries(n->mapper, n->prev, n->cap_prev, &n->n_prev))) goto fail;
        for (size_t i = 0; i < n->n_prev; i++)   /* a mapper without a box extent: the stored one */
            if (n->prev[i].extent[0] <= 0) memcpy(n->prev[i].extent, n->extent, sizeof n->extent);
        n->st.n_objects = n->n_prev;
    }

    /* shm table */
    if (c->shm_name[0]) {
        int rc = sooc_table_create_writer(c->shm_name, c->shm_capacity, 0, "map", &n->table);
        if (rc) {
            st = sooc_seterr(rc == SOOC_TABLE_ELOCKED ? SOOC_EBUSY : SOOC_EIO, "%s:shm.name: table '%s': %s",
                             c->path, c->shm_name, sooc_table_strerror(rc));
            goto fail;
        }
        sooc_table_start_heartbeat(n->table, 20.0);
        if ((uint64_t)n->n_prev > c->shm_capacity) {
            st = sooc_seterr(SOOC_EINVAL, "%s: shm.capacity: %u is below the %zu stored entries", c->path,
                             c->shm_capacity, n->n_prev);
            goto fail;
        }
    } else {
        sooc_log(SOOC_LOG_WARN, "%s: no shm.name: no object table for planners, the map goes to map.db only "
                                "(set shm.name, or --set shm.name=NAME)", c->path);
    }
    /* republish the resumed map (and clear leftovers of an earlier run); a map
     * preloaded by the caller also goes to a new database */
    if ((st = sooc__node_publish(n, n->prev, n->n_prev, NULL, 0, 1, !resumed, NULL))) goto fail;
    sooc_free(n->prev);
    n->prev = NULL;
    n->cap_prev = 0;
    *out = n;
    return SOOC_OK;
fail:
    sooc_node_destroy(n);
    return st;
}

/* ------------------------------------------------------------- capture */

static void *capture_main(void *arg) {
    sooc_node *n = arg;
    sooc_frame f;
    memset(&f, 0, sizeof f);
    sooc_status st = n->src.start ? n->src.start(n->src.ctx) : SOOC_OK;
    while (!st && !atomic_load(&n->stop)) {
        st = n->src.read(n->src.ctx, &f, 100);
        if (st == SOOC_ETIMEOUT) { st = SOOC_OK; continue; }
        if (st && st != SOOC_EEOF && st != SOOC_EINTERRUPTED && !(st = sooc__node_capture_skip(n, st))) continue;
        if (st && st != SOOC_EEOF && st != SOOC_EINTERRUPTED && !(st = sooc__node_reconnect(n, st))) continue;
        if (st) break;
        pthread_mutex_lock(&n->mu);
        n->st.frames_in++;
        pthread_mutex_unlock(&n->mu);
        sooc_frame_ring_push(n->ring, &f, sooc_now_ns());
    }
    if (st == SOOC_EEOF || st == SOOC_EINTERRUPTED) st = SOOC_OK;
    pthread_mutex_lock(&n->mu);
    uint64_t good = n->st.frames_in, bad = n->st.frames_skipped;
    pthread_mutex_unlock(&n->mu);
    if (!st && !good && bad)   /* a recording without one good frame is still an error */
        st = sooc_seterr(SOOC_EFORMAT, "none of the %llu frames of the recording could be read (the last: %s)",
                         (unsigned long long)bad, n->last_skip);
    if (st && !atomic_load(&n->stop)) {
        n->cap_status = st;
        snprintf(n->cap_err, sizeof n->cap_err, "%s", sooc_errmsg());
    }
    if (n->src.stop) n->src.stop(n->src.ctx);
    sooc_frame_free(&f);
    sooc_frame_ring_close(n->ring);   /* mapping drains what is left, then sees EEOF */
    return NULL;
}

/* ------------------------------------------------------------- mapping */

/* world.floor: estimate. The frame (pose known) waits in the support
 * buffer; when it is full (or the stream ended: final = 1) the support plane
 * is estimated from the buffered frames. Returns 1 when the world frame is
 * ready (the buffered frames are then to be mapped), 0 to keep waiting (on a
 * failed estimate the older half of the buffer is dropped), < 0 on error. */
static int try_support(sooc_node *n, const sooc_frame *f, const double T_src_c[16], int64_t t_cap, int final,
                       sooc_status *err) {
    if (f) {
        if (n->n_sup == n->cap_sup || sooc_frame_copy(&n->sup_f[n->n_sup], f)) {
            *err = sooc_seterr(SOOC_ENOMEM, "node: support-plane frame buffer");
            return -1;
        }
        n->sup_f[n->n_sup].has_pose = 1;
        memcpy(n->sup_f[n->n_sup].T_wc, T_src_c, 16 * sizeof(double));
        memcpy(n->sup_T + 16 * n->n_sup, T_src_c, 16 * sizeof(double));
        n->sup_tcap[n->n_sup] = t_cap;
        n->n_sup++;
    }
    if (n->n_sup == 0 || (n->n_sup < n->cap_sup && !final)) return 0;
    sooc_support_params sp;
    sooc__node_support_params(n, &sp);
    sp.max_frames = n->n_sup;
    const sooc_frame *fp[32];
    for (int i = 0; i < n->n_sup; i++) fp[i] = &n->sup_f[i];
    sooc_support sup;
    n->floor_attempts++;
    sooc_status st = sooc_support_estimate(fp, n->n_sup, &sp, &sup);
    if (st) {
        if (n->floor_attempts % 10 == 1 || final)
            sooc_log(SOOC_LOG_WARN, "node: support plane (world.floor: estimate) failed on frames %lld-%lld: %s",
                     (long long)n->sup_f[0].index, (long long)n->sup_f[n->n_sup - 1].index, sooc_errmsg());
        int drop = final ? n->n_sup : (n->n_sup + 1) / 2;
        for (int i = 0; i < n->n_sup; i++) {   /* keep the newer frames, swapping buffers */
            if (i + drop < n->n_sup) {
                sooc_frame t = n->sup_f[i];
                n->sup_f[i] = n->sup_f[i + drop];
                n->sup_f[i + drop] = t;
                memcpy(n->sup_T + 16 * i, n->sup_T + 16 * (i + drop), 16 * sizeof(double));
                n->sup_tcap[i] = n->sup_tcap[i + drop];
            }
        }
        n->n_sup -= drop;
        pthread_mutex_lock(&n->mu);
        n->st.frames_floor_wait += (uint64_t)drop;
        pthread_mutex_unlock(&n->mu);
        return 0;
    }
    set_world(n, sup.T_world_src);
    sooc_log(SOOC_LOG_INFO,
             "node: support plane from %d frames: n = (%.4f %.4f %.4f) d = %.4f, up from %s, tilt %.1f deg from it, "
             "%zu/%zu inliers, rms %.4f m, %d level planes; camera %.2f m above it",
             sup.frames_used, sup.plane_src[0], sup.plane_src[1], sup.plane_src[2], sup.plane_src[3],
             sooc_up_source_name(sup.up_source), sup.tilt_deg, sup.n_inliers, sup.n_points, sup.rms_m,
             sup.n_candidates, sup.cam_height_m);
    if (sup.height_warning)
        sooc_log(SOOC_LOG_WARN,
                 "node: the camera is %.2f m above the support plane, outside the %.2f-%.2f m the model was trained "
                 "for (world.camera_height_min_m / _max_m); objects may be mapped at the wrong scale",
                 sup.cam_height_m, sp.cam_height_min_m, sp.cam_height_max_m);
    sooc_map_frame mf;
    memset(&mf, 0, sizeof mf);
    memcpy(mf.T_world_src, sup.T_world_src, sizeof mf.T_world_src);
    memcpy(mf.up_src, sup.up_src, sizeof mf.up_src);
    memcpy(mf.plane_src, sup.plane_src, sizeof mf.plane_src);
    mf.cam_height_m = sup.cam_height_m;
    mf.up_source = (int)sup.up_source;
    if ((st = sooc__node_store_world(n, &mf))) {
        *err = st;
        return -1;
    }
    return 1;
}


/* pose.source: odometry. 1: T_src_c holds the frame's pose; 0: untracked
 * (counted and skipped: the mapper never sees a frame without a trusted
 * pose); -1: error (message set). */
static int odom_pose(sooc_node *n, sooc_frame *f, double T_src_c[16]) {
    sooc_odom_result r;
    if (sooc_odom_track(n->odom, f, &r)) return -1;
    if (r.state == SOOC_ODOM_FIRST || r.state == SOOC_ODOM_TRACKED) {
        if (n->odom_lost)
            sooc_log(SOOC_LOG_INFO, "node: odometry tracking again at frame %lld after %d untracked frames",
                     (long long)f->index, n->odom_lost);
        n->odom_lost = 0;
        memcpy(T_src_c, r.T_wc, 16 * sizeof(double));
        return 1;
    }
    if (!n->odom_lost)
        sooc_log(SOOC_LOG_WARN, "node: odometry lost tracking at frame %lld: frames are skipped until it recovers",
                 (long long)f->index);
    n->odom_lost++;
    if (r.state == SOOC_ODOM_REANCHORED)
        sooc_log(SOOC_LOG_WARN,
                 "node: odometry re-anchored at frame %lld after %d failures: poses continue from the last tracked "
                 "one (the map may be offset from here)",
                 (long long)f->index, n->odom_lost);
    pthread_mutex_lock(&n->mu);
    n->st.frames_untracked++;
    n->st.frames_no_pose++;
    pthread_mutex_unlock(&n->mu);
    return 0;
}

static void log_stats(sooc_node *n) {
    sooc_node_stats s;
    sooc_node_get_stats(n, &s);
    char line[512];
    sooc_node_stats_format(&s, line, sizeof line);
    sooc_log(SOOC_LOG_INFO, "node: %s", line);
    sooc__node_tracking_log(n);
}

/* Keyframe policy, preprocessing, mapper update and publishing of one frame
 * whose pose in the source frame is known. Returns 1 when the run must stop
 * (*result: an error, or SOOC_OK after max_keyframes), else 0. */
static int map_frame(sooc_node *n, sooc_frame *f, const double T_src_c[16], int64_t t_cap, sooc_status *result) {
    sooc_status st;
    double T_wc[16];
    sooc_se3_mul(T_wc, n->T_world_src, T_src_c);
    if (!sooc_kf_policy_check(&n->kf, T_wc, f->t_ns)) {
        pthread_mutex_lock(&n->mu);
        n->st.frames_not_kf++;
        pthread_mutex_unlock(&n->mu);
        return 0;
    }
    if ((st = sooc_frames_preprocess(f, &n->pre, n->tw, n->th, n->cfg.depth_resample, n->cfg.min_depth_m,
                                     n->cfg.max_depth_m))) {
        *result = st;
        return 1;
    }
    memcpy(n->pre.T_wc, T_wc, sizeof T_wc);
    n->pre.has_pose = 1;
    sooc_update_stats us;
    memset(&us, 0, sizeof us);
    double t0 = sooc_seconds();
    st = sooc_mapper_update(n->mapper, &n->pre, &us);
    double ms = (sooc_seconds() - t0) * 1e3;
    if (st) {
        pthread_mutex_lock(&n->mu);
        n->st.update_errors++;
        pthread_mutex_unlock(&n->mu);
        sooc_log(SOOC_LOG_WARN, "node: mapper update failed on frame %lld: %s", (long long)f->index,
                 sooc_errmsg());
        /* a late failure may have changed the map already: keep table and database in step */
        size_t pc = 0, pr = 0;
        if (!sooc_mapper_changed(n->mapper, NULL, 0, &pc, NULL, 0, &pr) && (pc || pr)) {
            sooc_status s2 = sooc__node_publish_keyframe(n, f->t_ns, T_wc, t_cap);
            if (s2) { *result = s2; return 1; }
        }
        if (st == SOOC_ENOMEM) { *result = st; return 1; }
        return 0;
    }
    sooc_kf_policy_accept(&n->kf, T_wc, f->t_ns);
    pthread_mutex_lock(&n->mu);
    sooc_latency_add(&n->lat_upd, ms);
    pthread_mutex_unlock(&n->mu);
    if ((st = sooc__node_publish_keyframe(n, f->t_ns, T_wc, t_cap))) { *result = st; return 1; }
    pthread_mutex_lock(&n->mu);
    n->st.keyframes++;
    uint64_t k = n->st.keyframes;
    pthread_mutex_unlock(&n->mu);
    /* the mapper's input frame (the model's size: the estimate samples at most 60,000 points anyway) */
    if ((st = sooc__node_floor_watch(n, &n->pre, T_src_c))) { *result = st; return 1; }
    if (n->view && sooc__node_view_publish(n, f))   /* the view is a window, not the map: warn */
        sooc_log(SOOC_LOG_WARN, "node: view: %s", sooc_errmsg());
    if (n->rec) sooc__node_record_keyframe(n, f->t_ns);
    sooc_log(SOOC_LOG_DEBUG, "node: keyframe %llu (frame %lld): %d retrieved, %d new, %d removed, %.1f ms",
             (unsigned long long)k, (long long)f->index, us.n_retrieved, us.n_new, us.n_removed, ms);
    if (n->opt.max_keyframes && k >= n->opt.max_keyframes) return 1;
    return 0;
}

/* Map the frames that waited for the support plane, in order, then free them. */
static int map_buffered(sooc_node *n, sooc_status *result) {
    int stop = 0;
    for (int i = 0; i < n->n_sup && !stop; i++) stop = map_frame(n, &n->sup_f[i], n->sup_T + 16 * i, n->sup_tcap[i], result);
    support_free(n);
    return stop;
}

sooc_status sooc_node_run(sooc_node *n) {
    if (!n->have_src) return sooc_seterr(SOOC_EINVAL, "node: no frame source");
    pthread_mutex_lock(&n->mu);   /* sooc_node_get_stats may run on another thread already */
    n->t_start = n->t_last_stats = sooc_seconds();
    pthread_mutex_unlock(&n->mu);
    if (pthread_create(&n->cap_thread, NULL, capture_main, n))
        return sooc_seterr(SOOC_ERR, "node: cannot start the capture thread");
    n->cap_started = 1;
    sooc_status result = SOOC_OK;
    int tracking = sooc__node_tracking_wanted(n);
    if (tracking && (result = sooc__node_tracking_start(n))) tracking = 0;
    int eof = 0;
    const int64_t tol_ns = (int64_t)llround(n->cfg.pose_tolerance_s * 1e9);
    while (!result && !atomic_load(&n->stop)) {
        if (n->cfg.stats_period_s > 0 && sooc_seconds() - n->t_last_stats >= n->cfg.stats_period_s) {
            n->t_last_stats = sooc_seconds();
            log_stats(n);
        }
        sooc_status st = sooc__node_store_retry(n, 0);
        if (st) { result = st; break; }
        int64_t t_cap = 0;
        st = tracking ? sooc__node_tracking_pop(n, &n->work, &t_cap, 100)
                      : sooc_frame_ring_pop(n->ring, &n->work, &t_cap, 100);
        if (st == SOOC_ETIMEOUT) continue;
        if (st == SOOC_EEOF) { eof = 1; break; }
        if (st) { result = st; break; }
        sooc_frame *f = &n->work;
        if (sooc__node_frame_size_skip(n, f, &result)) {
            if (result) break;
            continue;
        }
        sooc__node_time_check(n, f);
        /* pose association */
        double T_src_c[16];
        int fixed = 0;
        if (tracking) {   /* tracked on the tracking thread: registered, with its pose */
            if ((st = sooc__node_tracking_follow(n))) { result = st; break; }
            memcpy(T_src_c, f->T_wc, sizeof T_src_c);
            fixed = 1;
        } else if (n->cfg.pose_kind == SOOC_NODE_POSE_ODOMETRY && !n->opt.pose) {
            /* odometry tracks the colour-registered frame */
            if ((st = sooc__node_register_frame(n, f))) { result = st; break; }
            fixed = 1;
            int r = odom_pose(n, f, T_src_c);
            if (r < 0) { result = sooc_adderr(SOOC_ERR, "node: odometry"); break; }
            if (r == 0) continue;
        } else if ((n->cfg.pose_kind == SOOC_NODE_POSE_SENSOR || n->cfg.pose_kind == SOOC_NODE_POSE_TF) && !n->opt.pose) {
            if (!f->has_pose) {
                pthread_mutex_lock(&n->mu);
                n->st.frames_no_pose++;
                pthread_mutex_unlock(&n->mu);
                continue;
            }
            memcpy(T_src_c, f->T_wc, sizeof T_src_c);
        } else if (n->pose.lookup(n->pose.ctx, f->t_ns, tol_ns, T_src_c)) {
            pthread_mutex_lock(&n->mu);
            n->st.frames_no_pose++;
            pthread_mutex_unlock(&n->mu);
            sooc__node_pose_seen(n, f, 0);
            continue;
        } else {
            sooc__node_pose_seen(n, f, 1);
        }
        if (!fixed && (st = sooc__node_register_frame(n, f))) { result = st; break; }
        if (!n->world_ready) {
            int r = try_support(n, f, T_src_c, t_cap, 0, &result);
            if (r < 0) break;
            if (r == 0) continue;
            if (map_buffered(n, &result)) break;
            continue;
        }
        if (map_frame(n, f, T_src_c, t_cap, &result)) break;
    }
    /* the tracker's last optimisation (the stream's end verifies the last loop candidates) */
    if (!result && eof && tracking) result = sooc__node_tracking_follow(n);
    /* a stream that ended while frames waited for the support plane: estimate from those */
    if (!result && eof && !n->world_ready && n->n_sup > 0) {
        int r = try_support(n, NULL, NULL, 0, 1, &result);
        if (r > 0) map_buffered(n, &result);
    }
    /* shutdown: stop capture, join */
    sooc_node_request_stop(n);
    if (n->cap_started) {
        pthread_join(n->cap_thread, NULL);
        n->cap_started = 0;
    }
    if (tracking) {
        log_stats(n);
        sooc__node_tracking_stop(n);
    }
    if (!result && n->cap_status) {
        result = sooc_seterr(n->cap_status, "node: capture failed: %s", n->cap_err);
    }
    pthread_mutex_lock(&n->mu);
    uint64_t n_in = n->st.frames_in;
    pthread_mutex_unlock(&n->mu);
    if (!result && eof && n->map_skips && n->map_skips == n_in)   /* every frame read had the wrong size */
        result = sooc_seterr(SOOC_EINVAL, "none of the %llu frames of the recording could be mapped (the last: %s)",
                             (unsigned long long)n_in, n->cfg.calib_path);
    result = sooc__node_store_final(n, result);
    log_stats(n);
    return result;
}

void sooc_node_destroy(sooc_node *n) {
    if (!n) return;
    if (n->cap_started) {
        sooc_node_request_stop(n);
        pthread_join(n->cap_thread, NULL);
    }
    if (n->have_src && n->src.close) n->src.close(n->src.ctx);
    sooc_sensor_close(n->sensor);
    if (n->have_pose && n->pose.close) n->pose.close(n->pose.ctx);
    sooc_odom_destroy(n->odom);
    if (n->table) sooc_table_close_writer(n->table, n->cfg.shm_unlink_on_exit);
    sooc_sg_destroy(n->sg);
    sooc_mapstore_close(n->store);
    sooc__node_record_close(n);
    if (n->own_mapper) sooc_mapper_destroy(n->mapper);
    sooc_frame_ring_destroy(n->ring);
    sooc_view_stop(n->view);
    sooc_free(n->view_entries);
    sooc_free(n->view_objects);
    sooc_frame_free(&n->work);
    sooc_frame_free(&n->pre);
    sooc_free(n->reg_buf);
    support_free(n);
    sooc__node_floor_watch_free(n);
    sooc_free(n->prev);
    pthread_mutex_destroy(&n->mu);
    pthread_mutex_destroy(&n->sensor_mu);
    sooc_free(n);
}
