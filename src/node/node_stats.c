/* The node's statistics snapshot (sooc_node_get_stats) and the growth of its
 * arrays; shared by the mapping thread (pipeline.c) and the publisher
 * (publish.c). */
#include "node/node_impl.h"

#include <string.h>

sooc_status sooc__node_grow(void **p, size_t *cap, size_t need, size_t elem) {
    if (need <= *cap) return SOOC_OK;
    size_t nc = *cap ? *cap : 64;
    while (nc < need) nc *= 2;
    void *q = sooc_realloc(*p, nc * elem);
    if (!q) return sooc_seterr(SOOC_ENOMEM, "node: out of memory (%zu entries)", nc);
    *p = q;
    *cap = nc;
    return SOOC_OK;
}

void sooc__node_stats_refresh(sooc_node *n) {
    /* caller holds n->mu */
    n->st.update_p50_ms = sooc_latency_pct(&n->lat_upd, 0.5);
    n->st.update_p99_ms = sooc_latency_pct(&n->lat_upd, 0.99);
    n->st.c2t_p50_ms = sooc_latency_pct(&n->lat_c2t, 0.5);
    n->st.c2t_p99_ms = sooc_latency_pct(&n->lat_c2t, 0.99);
    n->st.publish_p50_ms = sooc_latency_pct(&n->lat_pub, 0.5);
    n->st.publish_p99_ms = sooc_latency_pct(&n->lat_pub, 0.99);
    if (n->ring) {
        uint64_t pushed, dropped;
        sooc_frame_ring_counts(n->ring, &pushed, &dropped, NULL);
        n->st.frames_dropped = dropped;
    }
    n->st.elapsed_s = sooc_seconds() - n->t_start;
    memcpy(n->st.T_world_src, n->T_world_src, sizeof n->T_world_src);
}


void sooc_node_get_stats(sooc_node *n, sooc_node_stats *out) {
    pthread_mutex_lock(&n->mu);
    sooc__node_stats_refresh(n);
    *out = n->st;
    pthread_mutex_unlock(&n->mu);
}
