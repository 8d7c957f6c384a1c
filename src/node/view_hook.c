/* The node's live view (launch view: {port, bind}; include/sooc3d/render.h):
 * after each keyframe the map's entries, the keyframe's colour frame and the
 * node's counters go to the view's server, which pushes them to browsers. */
#include "node_impl.h"

#include <math.h>
#include <stdio.h>

sooc_status sooc__node_view_publish(sooc_node *n, const sooc_frame *f) {
    size_t cnt = 0;
    sooc_status st = sooc_mapper_entries(n->mapper, NULL, 0, &cnt);
    if (st) return st;
    if (cnt > n->view_cap) {
        size_t cap = cnt + cnt / 2 + 16;
        sooc_map_entry *e = sooc_realloc(n->view_entries, cap * sizeof *e);
        sooc_view_object *o = sooc_realloc(n->view_objects, cap * sizeof *o);
        if (e) n->view_entries = e;
        if (o) n->view_objects = o;
        if (!e || !o) return sooc_seterr(SOOC_ENOMEM, "node: view: out of memory");
        n->view_cap = cap;
    }
    if ((st = sooc_mapper_entries(n->mapper, n->view_entries, n->view_cap, &cnt))) return st;
    for (size_t i = 0; i < cnt; i++) {
        const sooc_map_entry *e = &n->view_entries[i];
        double st, sy;
        sooc_map_entry_planner_sigmas(e, &st, &sy);
        double h = sooc_map_entry_height(e);
        n->view_objects[i] = (sooc_view_object){e->id, e->x, e->z, e->yaw, {e->extent[0], h, e->extent[2]},
                                                e->presence, st, sy, e->obs_count};
    }
    char stats[512];
    pthread_mutex_lock(&n->mu);
    snprintf(stats, sizeof stats,
             "{\"frames\": %llu, \"keyframes\": %llu, \"objects\": %llu, \"no_pose\": %llu, \"dropped\": %llu, "
             "\"skipped\": %llu, \"update_errors\": %llu}",
             (unsigned long long)n->st.frames_in, (unsigned long long)n->st.keyframes,
             (unsigned long long)n->st.n_objects, (unsigned long long)n->st.frames_no_pose,
             (unsigned long long)n->st.frames_dropped, (unsigned long long)n->st.frames_skipped,
             (unsigned long long)n->st.update_errors);
    pthread_mutex_unlock(&n->mu);
    return sooc_view_publish(n->view, n->view_objects, cnt, f->rgb, f->width, f->height, stats);
}
