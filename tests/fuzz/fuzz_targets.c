/*
 * sooc3d fuzz entry points (see fuzz_targets.h). Parsers that only take a
 * path get the bytes through a per-process temporary file.
 */
#include "fuzz_targets.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

#include <sqlite3.h>

#include "sooc3d/frame.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"
#include "sooc3d/log.h"
#include "sooc3d/model.h"
#include "sooc3d/node.h"
#include "sooc3d/gen.h"
#include "sooc3d/train.h"

/* ------------------------------------------------------------- helpers */

/* Write data to a per-process temporary file; returns its path (static). */
static const char *tmp_file(const char *tag, const uint8_t *data, size_t n) {
    static char path[512];
    const char *dir = getenv("TMPDIR");
    if (!dir || !*dir) dir = "/tmp";
    snprintf(path, sizeof path, "%s/sooc-fuzz-%ld-%s", dir, (long)getpid(), tag);
    FILE *f = fopen(path, "wb");
    if (!f) abort();   /* environment problem, not a finding */
    if (n && fwrite(data, 1, n, f) != n) abort();
    if (fclose(f)) abort();
    return path;
}

static void tmp_remove(const char *path) {
    char side[600];
    unlink(path);
    snprintf(side, sizeof side, "%s-wal", path);
    unlink(side);
    snprintf(side, sizeof side, "%s-shm", path);
    unlink(side);
    snprintf(side, sizeof side, "%s-journal", path);
    unlink(side);
}

/* A copy of d with the little-endian CRC-32 (zlib) of bytes [0, crc_at) stored
 * at crc_at, so that mutations of a CRC-guarded format reach the parser
 * behind the CRC check. NULL when the input is too short. */
static uint8_t *with_crc(const uint8_t *d, size_t n, size_t crc_at) {
    if (n < crc_at + 4) return NULL;
    uint8_t *c = malloc(n);
    if (!c) abort();
    memcpy(c, d, n);
    uint32_t crc = sooc_crc32(0, c, crc_at);
    for (int i = 0; i < 4; i++) c[crc_at + i] = (uint8_t)(crc >> (8 * i));
    return c;
}

/* Run `one` on the input as given and on a copy whose CRC field is fixed;
 * crc_at < 0 means the CRC is the last 4 bytes. Returns the first result. */
static int raw_and_crc(int (*one)(const uint8_t *, size_t), const uint8_t *d, size_t n, long crc_at) {
    int ok = one(d, n);
    size_t at = crc_at >= 0 ? (size_t)crc_at : n >= 4 ? n - 4 : n;
    uint8_t *c = with_crc(d, n, at);
    if (c) {
        one(c, n);
        free(c);
    }
    return ok;
}

/* ------------------------------------------------------------- targets */

static int fz_calib(const uint8_t *d, size_t n) {
    sooc_calib c;
    int ok = sooc_calib_parse((const char *)d, n, "fuzz.yaml", &c) == SOOC_OK;
    /* and through the file path (which blanks a leading %YAML:1.0 in place) */
    const char *p = tmp_file("calib.yaml", d, n);
    sooc_calib_load(p, &c);
    tmp_remove(p);
    return ok;
}

static int fz_scene(const uint8_t *d, size_t n) {
    const char *p = tmp_file("scene.yaml", d, n);
    sooc_scene sc;
    sooc_scene_init(&sc);
    int ok = sooc_scene_load(p, &sc) == SOOC_OK;
    if (ok) {
        /* touch what a loader promises: objects and views */
        double acc = 0;
        for (int i = 0; i < sc.n_objects; i++) {
            sooc_scene_part parts[SOOC_SCENE_MAX_PARTS];
            acc += sooc_scene_object_parts(&sc.objects[i], parts, SOOC_SCENE_MAX_PARTS);
            acc += sooc_scene_object_footprint(&sc.objects[i]);
        }
        for (int v = 0; v < sc.n_views; v++) {
            acc += sc.view_is_query[v];
            if (sc.view_T_wc) acc += sc.view_T_wc[16 * v + 3];
        }
        (void)acc;
    }
    sooc_scene_free(&sc);
    tmp_remove(p);
    return ok;
}

static int fz_train_config(const uint8_t *d, size_t n) {
    const char *p = tmp_file("train.yaml", d, n);
    sooc_train_config c;
    sooc_model_config mc;
    sooc_train_config_default(&c);
    sooc_model_config_default(&mc);
    int ok = sooc_train_config_load(p, &c, &mc) == SOOC_OK;
    tmp_remove(p);
    return ok;
}

static int fz_launch(const uint8_t *d, size_t n) {
    static sooc_node_config c;   /* ~7 KB: keep it off the stack */
    static char buf[16384];
    sooc_node_config_default(&c);
    int ok = sooc_node_config_parse(&c, (const char *)d, n, "fuzz_launch.yaml") == SOOC_OK;
    if (ok) {
        size_t need = sooc_node_config_format(&c, NULL, 0);  /* sizing */
        size_t part = sooc_node_config_format(&c, buf, 7);   /* truncated */
        size_t got = sooc_node_config_format(&c, buf, sizeof buf);
        if (need != got || part != got) abort();   /* snprintf-style: full length either way */
        sooc_node_param_get(&c, "uri");
    }
    return ok;
}

static int model_ckpt_one(const uint8_t *d, size_t n) {
    const char *p = tmp_file("model.ckpt", d, n);
    sooc_model *m = NULL;
    void *blob = NULL;
    size_t bn = 0;
    int ok = sooc_model_load(&m, p, &blob, &bn) == SOOC_OK;
    sooc_model_destroy(m);
    sooc_free(blob);
    tmp_remove(p);
    return ok;
}

static int fz_model_ckpt(const uint8_t *d, size_t n) { return raw_and_crc(model_ckpt_one, d, n, -1); }

typedef struct visit_acc { double s; int n; } visit_acc;
static int visit(void *user, const sooc_cogmap_entry *e) {
    visit_acc *a = user;
    a->s += e->pres_logit + e->what_mu[0];
    return ++a->n > 1000;
}

static int fz_mapstore(const uint8_t *d, size_t n) {
    const char *p = tmp_file("map.db", d, n);
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.create = 0;
    sooc_mapstore *s = NULL;
    int ok = sooc_mapstore_open(&s, p, &mp) == SOOC_OK;
    if (ok) {
        sooc_mapstore_info info;
        visit_acc acc = {0, 0};
        if (sooc_mapstore_info_get(s, &info) == SOOC_OK) {
            sooc_cogmap_params cp;
            sooc_cogmap_params_default(&cp);
            cp.dim = info.dim;
            cp.layout_dim = info.layout_dim;
            if (info.block_size > 0) cp.block_size = info.block_size;
            sooc_cogmap *map = NULL;
            if (sooc_cogmap_create(&map, &cp) == SOOC_OK) {
                if (sooc_mapstore_load_map(s, map) == SOOC_OK) {
                    sooc_cogmap_foreach(map, visit, &acc);
                    /* ids are never reused: a new entry must not replace a loaded one */
                    sooc_cogmap_entry e;
                    memset(&e, 0, sizeof e);
                    e.dim = info.dim;
                    e.obs_count = 1;
                    size_t before = sooc_cogmap_count(map);
                    if (sooc_cogmap_insert(map, &e, NULL) == SOOC_OK && sooc_cogmap_count(map) != before + 1)
                        abort();
                }
                sooc_cogmap_destroy(map);
            }
        }
        sooc_mapstore_foreach(s, visit, &acc);
        acc.n = 0;
        sooc_mapstore_query_box(s, -5, -5, 5, 5, visit, &acc);
        sooc_cogmap_entry e;
        sooc_mapstore_get(s, 1, &e);
        sooc_mapstore_close(s);
    }
    tmp_remove(p);
    return ok;
}

/* mapstore_sql: the input is SQL run against a valid map (2-d entries,
 * 1-d layout, 3 entries, a layout block, a keyframe); then the map is opened
 * and read as in fz_mapstore. Reaches the row/meta validation that random
 * bytes of a SQLite file rarely do. ATTACH, VACUUM (INTO) and PRAGMA are
 * refused so the SQL cannot touch other files. */
static int deny_cb(void *u, int code, const char *a, const char *b, const char *c, const char *d) {
    (void)u; (void)a; (void)b; (void)c; (void)d;
    return code == SQLITE_ATTACH || code == SQLITE_DETACH || code == SQLITE_PRAGMA ? SQLITE_DENY : SQLITE_OK;
}
static int progress_cb(void *u) { return ++*(int *)u > 2000; }   /* stop runaway CTEs */

static uint8_t *g_tmpl;
static size_t g_tmpl_n;

static void make_template(void) {
    const char *p = tmp_file("tmpl.db", (const uint8_t *)"", 0);
    tmp_remove(p);
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = 2;
    cp.layout_dim = 1;
    sooc_cogmap *map = NULL;
    sooc_mapstore *s = NULL;
    sooc_mapstore_params mp;
    sooc_mapstore_params_default(&mp);
    mp.dim = 2;
    mp.layout_dim = 1;
    mp.block_size = 4;
    if (sooc_cogmap_create(&map, &cp) || sooc_mapstore_open(&s, p, &mp)) abort();
    for (int i = 0; i < 3; i++) {
        sooc_cogmap_entry e;
        memset(&e, 0, sizeof e);
        e.X = i; e.Z = -i; e.pres_logit = 1; e.dim = 2; e.what_mu[0] = 0.5f; e.obs_count = 1;
        if (sooc_cogmap_insert(map, &e, NULL)) abort();
    }
    float mu = 0.25f, lv = -1;
    sooc_mapstore_keyframe kf;
    memset(&kf, 0, sizeof kf);
    kf.T_wc[0] = kf.T_wc[5] = kf.T_wc[10] = kf.T_wc[15] = 1;
    if (sooc_mapstore_save_map(s, map) || sooc_mapstore_begin(s) || sooc_mapstore_put_layout(s, 0, 0, &mu, &lv) ||
        sooc_mapstore_add_keyframe(s, &kf, 3) || sooc_mapstore_commit(s))
        abort();
    sooc_mapstore_close(s);
    sooc_cogmap_destroy(map);
    void *buf;
    if (sooc_file_read_all(p, (size_t)1 << 24, &buf, &g_tmpl_n)) abort();
    g_tmpl = malloc(g_tmpl_n);
    if (!g_tmpl) abort();
    memcpy(g_tmpl, buf, g_tmpl_n);
    sooc_free(buf);
    tmp_remove(p);
}

static int fz_mapstore_sql(const uint8_t *d, size_t n) {
    if (n > 4096) return 0;
    if (!g_tmpl) make_template();
    char *sql = malloc(n + 1);
    if (!sql) abort();
    memcpy(sql, d, n);
    sql[n] = 0;
    for (char *c = sql; *c; c++)   /* VACUUM INTO writes a file: refuse any vacuum */
        if ((c[0] | 32) == 'v' && !strncasecmp(c, "vacuum", 6)) { free(sql); return 0; }
    const char *p = tmp_file("sql.db", g_tmpl, g_tmpl_n);
    sqlite3 *db = NULL;
    int steps = 0;
    if (sqlite3_open_v2(p, &db, SQLITE_OPEN_READWRITE, NULL) == SQLITE_OK) {
        sqlite3_set_authorizer(db, deny_cb, NULL);
        sqlite3_progress_handler(db, 100, progress_cb, &steps);
        sqlite3_limit(db, SQLITE_LIMIT_LENGTH, 1 << 20);
        sqlite3_exec(db, sql, NULL, NULL, NULL);
    }
    sqlite3_close(db);
    free(sql);
    /* the rest is fz_mapstore on the modified file */
    void *buf;
    size_t m;
    int ok = 0;
    if (sooc_file_read_all(p, (size_t)1 << 24, &buf, &m) == SOOC_OK) {
        tmp_remove(p);
        ok = fz_mapstore(buf, m);
        sooc_free(buf);
    }
    tmp_remove(p);
    return ok;
}

static int pose_packet_one(const uint8_t *d, size_t n) {
    sooc_pose_packet pk;
    if (sooc_pose_packet_decode(d, n, &pk) != SOOC_OK) return 0;
    int ok = 1;
    /* a decoded packet goes into the ring as the receiver thread does */
    sooc_pose_params pp;
    sooc_pose_params_default(&pp);
    pp.capacity = 4;
    sooc_pose_src *src = NULL;
    if (sooc_pose_open_buffer(&src, &pp) == SOOC_OK) {
        double T[16];
        ok = sooc_pose_push_tq(src, pk.t_ns, pk.kind, pk.t, pk.q) == SOOC_OK;
        sooc_pose_lookup(src, pk.t_ns, 1000000, T);
        sooc_pose_close(src);
    }
    return ok;
}

/* Bytes 80..83 hold the CRC of bytes 0..79. */
static int fz_pose_packet(const uint8_t *d, size_t n) { return raw_and_crc(pose_packet_one, d, n, 80); }

static int fz_tum(const uint8_t *d, size_t n) {
    const char *p = tmp_file("groundtruth.txt", d, n);
    sooc_pose_src *src = NULL;
    int ok = sooc_pose_open_file(&src, p, NULL) == SOOC_OK;
    if (ok) {
        sooc_pose_stats st;
        double T[16];
        sooc_pose_get_stats(src, &st);
        int64_t mid = st.t_first_ns / 2 + st.t_last_ns / 2;
        sooc_pose_lookup(src, st.t_first_ns, 0, T);
        sooc_pose_lookup(src, mid, INT64_MAX / 4, T);
        sooc_pose_lookup(src, st.t_last_ns, 1000, T);
        sooc_pose_close(src);
    }
    tmp_remove(p);
    return ok;
}

static void touch_image(const sooc_image *img) {
    size_t bytes = (size_t)img->width * (size_t)img->height * (size_t)sooc_pixfmt_bytes(img->fmt);
    volatile unsigned acc = 0;
    if (bytes) acc += ((const uint8_t *)img->data)[0] + ((const uint8_t *)img->data)[bytes - 1];
    (void)acc;
}

static int fz_png(const uint8_t *d, size_t n) {
    const char *p = tmp_file("img.png", d, n);
    sooc_image img = {0};
    int w, h;
    sooc_pixfmt fmt;
    sooc_png_info(p, &w, &h, &fmt);
    int ok = sooc_png_read(p, &img) == SOOC_OK;
    if (ok) touch_image(&img);
    sooc_image_free(&img);
    tmp_remove(p);
    return ok;
}

static int fz_pgm(const uint8_t *d, size_t n) {
    const char *p = tmp_file("img.pgm", d, n);
    sooc_image img = {0};
    int ok = sooc_pgm_read(p, &img) == SOOC_OK;
    if (ok) touch_image(&img);
    sooc_image_free(&img);
    if (sooc_image_read(p, &img) == SOOC_OK) touch_image(&img);
    sooc_image_free(&img);
    tmp_remove(p);
    return ok;
}

/* JPEG from memory (the V4L2 MJPEG path), then as a file by content. */
static int fz_jpeg(const uint8_t *d, size_t n) {
    sooc_image img = {0};
    int ok = sooc_jpeg_decode(d, n, "fuzz.jpg", &img) == SOOC_OK;
    if (ok) touch_image(&img);
    sooc_image_free(&img);
    const char *p = tmp_file("img.jpg", d, n);
    int w, h;
    sooc_pixfmt fmt;
    sooc_image_info(p, &w, &h, &fmt);
    if (sooc_image_read(p, &img) == SOOC_OK) touch_image(&img);
    sooc_image_free(&img);
    tmp_remove(p);
    return ok;
}

/* A ROS bag or MCAP file: open, read every message (at most 10000), check
 * the CRCs, then the frames path (topics, CameraInfo, TF, up to 3 frames). */
static int log_file(const uint8_t *d, size_t n, const char *tag) {
    const char *p = tmp_file(tag, d, n);
    sooc_logfile *lf = NULL;
    int ok = sooc_logfile_open(&lf, p) == SOOC_OK;
    if (ok) {
        for (int64_t k = 0; k < sooc_logfile_count(lf) && k < 10000; k++) {
            sooc_logfile_msg m;
            if (sooc_logfile_read(lf, k, &m) == SOOC_OK && m.size) {
                volatile uint8_t a = m.data[0] ^ m.data[m.size - 1];
                (void)a;
            }
        }
        sooc_logfile_verify(lf);
        sooc_logfile_close(lf);
        sooc_logseq_params lp;
        sooc_logseq_params_default(&lp);
        lp.pose_parent = "auto";
        sooc_logseq *s = NULL;
        if (sooc_logseq_open(&s, p, &lp) == SOOC_OK) {
            sooc_frame f = {0};
            for (int64_t i = 0; i < sooc_logseq_count(s) && i < 3; i++) sooc_logseq_read(s, i, &f);
            sooc_frame_free(&f);
            sooc_logseq_close(s);
        }
    }
    tmp_remove(p);
    return ok;
}
static int fz_rosbag(const uint8_t *d, size_t n) { return log_file(d, n, "log.bag"); }
static int fz_mcap(const uint8_t *d, size_t n) { return log_file(d, n, "log.mcap"); }

/* One message's bytes decoded as every type the readers know. */
static int msg_all(const uint8_t *d, size_t n, sooc_msg_encoding enc) {
    static const char *poses[] = {"geometry_msgs/TransformStamped", "geometry_msgs/Transform", "geometry_msgs/msg/PoseStamped",
                                  "geometry_msgs/Pose", "nav_msgs/msg/Odometry"};
    sooc_ros_image im;
    sooc_ros_cimage ci;
    sooc_ros_caminfo k;
    sooc_ros_transform tf[4];
    int nt, ok = 0;
    double v;
    if (sooc_ros_decode_image(d, n, enc, &im) == SOOC_OK) {
        ok = 1;
        if (im.size) {
            volatile uint8_t a = im.data[0] ^ im.data[im.size - 1];
            (void)a;
        }
    }
    if (sooc_ros_decode_cimage(d, n, enc, &ci) == SOOC_OK) {
        ok = 1;
        sooc_image img = {0};
        if (ci.size && ci.size < (1u << 20)) sooc_jpeg_decode(ci.data, ci.size, "fuzz", &img);
        sooc_image_free(&img);
    }
    ok |= sooc_ros_decode_caminfo(d, n, enc, &k) == SOOC_OK;
    ok |= sooc_ros_decode_tf(d, n, enc, tf, 4, &nt) == SOOC_OK;
    for (size_t i = 0; i < sizeof poses / sizeof poses[0]; i++) ok |= sooc_ros_decode_pose(poses[i], d, n, enc, tf) == SOOC_OK;
    ok |= sooc_ros_decode_float("std_msgs/Float64", d, n, enc, &v) == SOOC_OK;
    return ok;
}
static int fz_ros1msg(const uint8_t *d, size_t n) { return msg_all(d, n, SOOC_MSGENC_ROS1); }
static int fz_cdrmsg(const uint8_t *d, size_t n) { return msg_all(d, n, SOOC_MSGENC_CDR); }

/* fuzz_targets_seq.c */
int sooc_fuzz_ycb_meta(const uint8_t *d, size_t n);
int sooc_fuzz_apc(const uint8_t *d, size_t n);
int sooc_fuzz_node_set(const uint8_t *d, size_t n);

const sooc_fuzz_target sooc_fuzz_targets[] = {
    {"calib", fz_calib},
    {"scene", fz_scene},
    {"train_config", fz_train_config},
    {"launch", fz_launch},
    {"model_ckpt", fz_model_ckpt},
    {"mapstore", fz_mapstore},
    {"mapstore_sql", fz_mapstore_sql},
    {"pose_packet", fz_pose_packet},
    {"tum", fz_tum},
    {"png", fz_png},
    {"pgm", fz_pgm},
    {"jpeg", fz_jpeg},
    {"rosbag", fz_rosbag},
    {"mcap", fz_mcap},
    {"ros1msg", fz_ros1msg},
    {"cdrmsg", fz_cdrmsg},
    {"ycb_meta", sooc_fuzz_ycb_meta},
    {"apc", sooc_fuzz_apc},
    {"node_set", sooc_fuzz_node_set},
    {NULL, NULL},
};

const sooc_fuzz_target *sooc_fuzz_find(const char *name) {
    for (const sooc_fuzz_target *t = sooc_fuzz_targets; t->name; t++)
        if (!strcmp(t->name, name)) return t;
    return NULL;
}
