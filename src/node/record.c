/* The node's recording for Foxglove (launch record: {mcap: FILE, period_s};
 * docs/logs.md "Foxglove"): the channels of `sooc3d map export --mcap`
 * (/sooc3d/objects foxglove.SceneUpdate, /sooc3d/frames foxglove.FrameTransform
 * map -> world and world -> source, the pose source's frame, as the node last
 * placed it) written while the node runs. After each keyframe a SceneUpdate
 * holding every object of the map is kept; at most every period_s, and when
 * the node is destroyed, the file is written again whole through the MCAP
 * writer's temporary file and rename, so the path always holds a finished
 * file (summary, chunk indexes, statistics, CRCs) that any MCAP reader opens:
 * a node that is killed leaves the file of its last write. At most
 * REC_KEEP updates are kept: when full, every other one is dropped (the first
 * and the latest stay), so a long run keeps an even sample of its history and
 * the file's size is bounded. Chunks are not compressed (JSON, small). A
 * failed write is said once per change of state and the node goes on. */
#include "node_impl.h"
#include "sooc3d/log.h"

#include <math.h>
#include <stdio.h>
#include <string.h>

#define REC_KEEP 128

typedef struct rec_msg {
    int64_t t_ns;
    sooc_ros_buf b;    /* the JSON; its buffer is reused */
} rec_msg;

struct sooc__recorder {
    char path[512];
    double period_s, t_written;
    int dirty, failing;
    rec_msg msg[REC_KEEP];
    int n;
    int64_t t0;
    sooc_map_entry *ent;
    size_t cap;
    uint64_t writes;
    double T_ws[16];   /* world <- source at the latest keyframe */
    int has_ws;
};

static sooc_status rec_write(sooc__recorder *r) {
    sooc_mcap_writer_params wp;
    sooc_mcap_writer_params_default(&wp);
    wp.compression = "";
    sooc_mcap_writer *w = NULL;
    int sc_scene, sc_frame, ch_scene, ch_frame;
    sooc_ros_buf b = {0};
    sooc_status st = sooc_mcap_writer_open(&w, r->path, &wp);
    if (!st)
        st = sooc_mcap_writer_schema(w, "foxglove.SceneUpdate", "jsonschema", sooc_foxglove_scene_schema,
                                     strlen(sooc_foxglove_scene_schema), &sc_scene);
    if (!st)
        st = sooc_mcap_writer_schema(w, "foxglove.FrameTransform", "jsonschema", sooc_foxglove_frame_schema,
                                     strlen(sooc_foxglove_frame_schema), &sc_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_frame, "/sooc3d/frames", "json", &ch_frame);
    if (!st) st = sooc_mcap_writer_channel(w, sc_scene, "/sooc3d/objects", "json", &ch_scene);
    if (!st) {
        sooc_foxglove_frame(&b, r->t0, "map", "world", sooc_foxglove_T_map_world);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, r->t0, r->t0, b.data, b.size);
    }
    if (!st && r->has_ws) {
        b.size = 0;
        sooc_foxglove_frame(&b, r->t0, "world", "source", r->T_ws);
        st = b.oom ? SOOC_ENOMEM : sooc_mcap_writer_message(w, ch_frame, r->t0, r->t0, b.data, b.size);
    }
    sooc_ros_buf_free(&b);
    for (int i = 0; i < r->n && !st; i++)
        st = sooc_mcap_writer_message(w, ch_scene, r->msg[i].t_ns, r->msg[i].t_ns, r->msg[i].b.data, r->msg[i].b.size);
    if (st) {
        sooc_mcap_writer_abort(w);
        return st;
    }
    return sooc_mcap_writer_close(w);
}

/* Write now; say so once when writing starts or stops failing. */
static void rec_flush(sooc__recorder *r) {
    sooc_status st = rec_write(r);
    if (st && !r->failing)
        sooc_log(SOOC_LOG_WARN, "node: record: cannot write %s: %s (the node goes on; retried at the next keyframe)",
                 r->path, sooc_errmsg());
    if (!st && r->failing) sooc_log(SOOC_LOG_WARN, "node: record: %s written again", r->path);
    r->failing = st != SOOC_OK;
    r->dirty = r->failing;
    r->t_written = sooc_seconds();
    r->writes += !st;
}

sooc_status sooc__node_record_open(sooc_node *n) {
    if (!n->cfg.record_mcap[0]) return SOOC_OK;
    sooc__recorder *r = sooc_calloc(1, sizeof *r);
    if (!r) return SOOC_ENOMEM;
    snprintf(r->path, sizeof r->path, "%s", n->cfg.record_mcap);
    r->period_s = n->cfg.record_period_s;
    /* an empty file now: a path that cannot be written is an error at start */
    sooc_status st = rec_write(r);
    if (st) {
        sooc_free(r);
        return sooc_adderr(st, "%s: record.mcap", n->cfg.path);
    }
    r->t_written = sooc_seconds();
    n->rec = r;
    sooc_log(SOOC_LOG_INFO, "node: recording the map's SceneUpdates to %s (rewritten at most every %.3g s)", r->path,
             r->period_s);
    return SOOC_OK;
}

void sooc__node_record_keyframe(sooc_node *n, int64_t t_ns) {
    sooc__recorder *r = n->rec;
    size_t cnt = 0;
    sooc_status st = sooc_mapper_entries(n->mapper, NULL, 0, &cnt);
    if (!st && cnt > r->cap) {
        size_t cap = cnt + cnt / 2 + 16;
        sooc_map_entry *e = sooc_realloc(r->ent, cap * sizeof *e);
        if (!e) st = SOOC_ENOMEM;
        else r->ent = e, r->cap = cap;
    }
    if (!st) st = sooc_mapper_entries(n->mapper, r->ent, r->cap, &cnt);
    if (st) {
        sooc_log(SOOC_LOG_WARN, "node: record: %s", sooc_errmsg());
        return;
    }
    if (!r->n) r->t0 = t_ns;
    memcpy(r->T_ws, n->T_world_src, sizeof r->T_ws);   /* the mapping thread's own field: no lock to read it */
    r->has_ws = n->world_ready;
    if (r->n == REC_KEEP) {   /* keep 0, 2, 4, ...: their buffers move down, the others' go to the free end */
        for (int i = 1; i < REC_KEEP / 2; i++) {
            rec_msg tmp = r->msg[i];
            r->msg[i] = r->msg[2 * i];
            r->msg[2 * i] = tmp;
        }
        r->n = REC_KEEP / 2;
    }
    rec_msg *m = &r->msg[r->n];
    m->t_ns = t_ns;
    m->b.size = 0;
    m->b.oom = 0;
    sooc_foxglove_printf(&m->b, "{\"deletions\": [], \"entities\": [");
    for (size_t i = 0; i < cnt; i++) {
        const sooc_map_entry *e = &r->ent[i];
        double cov[4];
        sooc_map_entry_planner_cov(e, cov);
        double h = sooc_map_entry_height(e);
        if (i) sooc_foxglove_printf(&m->b, ", ");
        sooc_foxglove_entity(&m->b, e, cov, h, t_ns);
    }
    sooc_foxglove_printf(&m->b, "]}");
    if (m->b.oom) {
        sooc_log(SOOC_LOG_WARN, "node: record: out of memory for a SceneUpdate of %zu objects", cnt);
        return;
    }
    r->n++;
    r->dirty = 1;
    if (sooc_seconds() - r->t_written >= r->period_s) rec_flush(r);
}

void sooc__node_record_close(sooc_node *n) {
    sooc__recorder *r = n->rec;
    if (!r) return;
    if (r->dirty) rec_flush(r);
    if (!r->failing)
        sooc_log(SOOC_LOG_INFO, "node: record: %s holds %d SceneUpdate(s), the last with every object", r->path, r->n);
    for (int i = 0; i < REC_KEEP; i++) sooc_ros_buf_free(&r->msg[i].b);
    sooc_free(r->ent);
    sooc_free(r);
    n->rec = NULL;
}
