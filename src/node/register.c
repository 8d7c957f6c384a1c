/* A captured frame's intrinsics from the calibration (scaled to the frame's
 * size) and its depth registered to the colour camera when the calibration
 * says it is not (node_impl.h sooc__node_register_frame). Used by the capture
 * path and by the tracking thread's frame source. */
#include "node/node_impl.h"

sooc_status sooc__node_register_frame(sooc_node *n, sooc_frame *f) {
    if (!n->have_calib) {
        if (f->K.fx == 0 || f->K.fy == 0)
            return sooc_seterr(SOOC_EINVAL, "%s: the sensor gives no intrinsics; set calib: to a calib file",
                               n->cfg.path);
        if (f->K.width <= 0) { f->K.width = f->width; f->K.height = f->height; }
        return SOOC_OK;
    }
    sooc_intrinsics Kc = n->Kc;
    if (Kc.width != f->width || Kc.height != f->height) {
        /* same aspect ratio: scale the calibration */
        if ((long)Kc.width * f->height != (long)Kc.height * f->width)
            return sooc_seterr(SOOC_EINVAL, "%s: calib is for %dx%d but the sensor gives %dx%d",
                               n->cfg.calib_path, Kc.width, Kc.height, f->width, f->height);
        sooc_intrinsics s;
        sooc_cam_crop_resize(&s, &Kc, 0, 0, Kc.width, Kc.height, f->width, f->height);
        Kc = s;
    }
    if (n->calib_registered == 0 && n->have_T_cd) {
        /* depth is in the depth camera: the frame's K is the depth camera's */
        sooc_intrinsics Kd = f->K;
        if (Kd.fx == 0) Kd = Kc;   /* no depth intrinsics reported: assume the colour ones */
        Kd.width = f->width;
        Kd.height = f->height;
        size_t np = (size_t)f->width * f->height;
        if (n->reg_cap < np) {
            sooc_free(n->reg_buf);
            n->reg_buf = sooc_malloc(np * sizeof(float));
            if (!n->reg_buf) { n->reg_cap = 0; return SOOC_ENOMEM; }
            n->reg_cap = np;
        }
        sooc_frames_register_depth(f->depth, &Kd, n->T_cd, &Kc, n->reg_buf);
        memcpy(f->depth, n->reg_buf, np * sizeof(float));
        for (size_t i = 0; i < np; i++) f->valid[i] = f->depth[i] > 0.0f;
    }
    f->K = Kc;
    return SOOC_OK;
}
