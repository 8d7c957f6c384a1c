/* Frame buffers. */
#include "sooc3d/frame.h"

#include <string.h>

sooc_status sooc_frame_alloc(sooc_frame *f, int w, int h, int with_instance) {
    memset(f, 0, sizeof *f);
    if (w <= 0 || h <= 0 || w > 16384 || h > 16384)
        return sooc_seterr(SOOC_EINVAL, "frame size %dx%d out of range", w, h);
    size_t n = (size_t)w * (size_t)h;
    f->rgb = sooc_calloc(n, 3);
    f->depth = sooc_calloc(n, sizeof(float));
    f->valid = sooc_calloc(n, 1);
    f->instance = with_instance ? sooc_calloc(n, sizeof(uint16_t)) : NULL;
    if (!f->rgb || !f->depth || !f->valid || (with_instance && !f->instance)) {
        sooc_frame_free(f);
        return SOOC_ENOMEM;
    }
    f->width = w;
    f->height = h;
    sooc_se3_identity(f->T_wc);
    return SOOC_OK;
}

void sooc_frame_free(sooc_frame *f) {
    if (!f) return;
    sooc_free(f->rgb);
    sooc_free(f->depth);
    sooc_free(f->valid);
    sooc_free(f->instance);
    memset(f, 0, sizeof *f);
}

sooc_status sooc_frame_copy(sooc_frame *dst, const sooc_frame *src) {
    if (dst == src) return SOOC_OK;
    size_t np = (size_t)src->width * (size_t)src->height;
    if (dst->rgb && dst->depth && dst->valid && dst->width == src->width && dst->height == src->height &&
        !dst->instance == !src->instance) {   /* same size: into dst's own buffers */
        uint8_t *rgb = dst->rgb, *valid = dst->valid;
        float *depth = dst->depth;
        uint16_t *inst = dst->instance;
        *dst = *src;
        dst->rgb = rgb, dst->depth = depth, dst->valid = valid, dst->instance = inst;
        memcpy(rgb, src->rgb, np * 3);
        memcpy(depth, src->depth, np * sizeof(float));
        memcpy(valid, src->valid, np);
        if (inst) memcpy(inst, src->instance, np * sizeof(uint16_t));
        return SOOC_OK;
    }
    sooc_frame tmp;
    sooc_status s = sooc_frame_alloc(&tmp, src->width, src->height, src->instance != NULL);
    if (s) return s;
    size_t n = (size_t)src->width * (size_t)src->height;
    uint8_t *rgb = tmp.rgb, *valid = tmp.valid;
    float *depth = tmp.depth;
    uint16_t *inst = tmp.instance;
    tmp = *src;
    tmp.rgb = rgb; tmp.depth = depth; tmp.valid = valid; tmp.instance = inst;
    memcpy(tmp.rgb, src->rgb, n * 3);
    memcpy(tmp.depth, src->depth, n * sizeof(float));
    memcpy(tmp.valid, src->valid, n);
    if (inst) memcpy(tmp.instance, src->instance, n * sizeof(uint16_t));
    sooc_frame_free(dst);
    *dst = tmp;
    return SOOC_OK;
}
