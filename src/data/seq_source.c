/* Sequences whose frames another reader makes (sooc_seq_open_source): the
 * index holds their stamps, reads go to the reader, and the sequence applies
 * its depth limit as the directory layouts do. */
#include "seq_impl.h"

#include <stdio.h>
#include <string.h>

sooc_status sooc_seq_open_source(sooc_seq **out, const sooc_seq_source *src) {
    *out = NULL;
    sooc_seq *s = sooc_calloc(1, sizeof *s);
    if (!s) {
        if (src->close) src->close(src->user);
        return SOOC_ENOMEM;
    }
    s->priv = src->user;
    s->priv_free = src->close;
    s->source_read = src->read;
    s->fmt = SOOC_SEQ_SOURCE;
    snprintf(s->dir, sizeof s->dir, "%s", src->name ? src->name : "source");
    sooc_calib_init(&s->calib);
    if (src->calib) s->calib = *src->calib;
    s->max_depth = src->max_depth;
    s->depth_scale = s->calib.depth_scale;
    for (int64_t i = 0; i < src->n; i++) {
        sooc_seqi_entry *e;
        sooc_status st = sooc_seqi_push(s, &e);
        if (st) {
            sooc_seq_close(s);
            return st;
        }
        e->t_ns = src->t_ns[i];
        e->number = i;
    }
    *out = s;
    return SOOC_OK;
}

sooc_status sooc_seqi_source_read(sooc_seq *s, int64_t i, sooc_frame *f) {
    sooc_status st = s->source_read(s->priv, i, f);
    if (st) return st;
    if (s->max_depth > 0) {
        size_t np = (size_t)f->width * (size_t)f->height;
        for (size_t k = 0; k < np; k++)
            if (f->depth[k] > s->max_depth) {
                f->depth[k] = 0;
                f->valid[k] = 0;
            }
    }
    return SOOC_OK;
}
