/* Logs as sequences: sooc_log_seq_open hands a sooc_logseq to the data
 * module's sequence interface, so every command that reads a folder reads a
 * ROS bag or an MCAP file the same way. */
#include "sooc3d/frame.h"
#include "sooc3d/log.h"

#include <stdio.h>
#include <string.h>

static sooc_status src_read(void *user, int64_t i, sooc_frame *f) { return sooc_logseq_read(user, i, f); }
static void src_close(void *user) { sooc_logseq_close(user); }

sooc_status sooc_log_seq_open(sooc_seq **out, const char *path, const sooc_seq_open_params *spp,
                              const sooc_logseq_params *lpp) {
    *out = NULL;
    sooc_seq_open_params sp;
    if (spp) sp = *spp;
    else sooc_seq_open_params_default(&sp);
    sooc_logfile_kind kind = sooc_logfile_detect(path);
    if (kind == SOOC_LOGFILE_NONE) return sooc_seq_open(out, path, &sp);
    if (sp.format != SOOC_SEQ_AUTO)
        return sooc_seterr(SOOC_EINVAL, "%s: a %s file: the sequence format '%s' applies to folders", path,
                           sooc_logfile_kind_name(kind), sooc_seq_format_name(sp.format));
    sooc_logseq_params lp;
    if (lpp) lp = *lpp;
    else {
        sooc_logseq_params_default(&lp);
        lp.pose_parent = "auto";
        if (sp.max_dt > 0) lp.pair_tol_s = sp.max_dt;
    }
    if (sp.depth_scale > 0) lp.depth_scale = sp.depth_scale;
    if (sp.max_depth > 0) lp.max_depth = sp.max_depth;
    sooc_calib cal;
    sooc_calib_init(&cal);
    sooc_status st = sp.calib_path && *sp.calib_path ? sooc_calib_load(sp.calib_path, &cal) : SOOC_OK;
    if (st) return st;
    sooc_logseq *ls = NULL;
    if ((st = sooc_logseq_open(&ls, path, &lp))) return st;
    const sooc_logseq_desc *d = sooc_logseq_describe(ls);
    if (sp.calib_path && *sp.calib_path) {
        if (cal.K.width != d->color.width || cal.K.height != d->color.height)
            st = sooc_seterr(SOOC_EINVAL, "%s: calibration is %dx%d but colour %s is %dx%d", sp.calib_path,
                             cal.K.width, cal.K.height, d->color.topic, d->color.width, d->color.height);
    } else if (!d->color.has_info) {
        st = sooc_seterr(SOOC_EFORMAT, "%s: colour %s has no CameraInfo of its size: give a calibration (--calib, "
                         "launch calib:)", path, d->color.topic);
    } else {
        cal.K = d->color.K;
    }
    if (!st && d->n_frames == 0)
        st = sooc_seterr(SOOC_EFORMAT,
                         "%s: none of the %lld colour images of %s has a depth image of %s within %.0f ms (nearest "
                         "%.0f ms): raise the pairing tolerance (sensor.pair_tol_ms)",
                         path, (long long)d->n_unpaired, d->color.topic, d->depth.topic, lp.pair_tol_s * 1e3,
                         d->nearest_unpaired_s * 1e3);
    if (st) {
        sooc_logseq_close(ls);
        return st;
    }
    cal.depth_scale = d->depth_scale > 0 ? d->depth_scale : 1.0;
    int64_t n = sooc_logseq_count(ls);
    int64_t *t = sooc_malloc(sizeof(int64_t) * (size_t)n);
    if (!t) {
        sooc_logseq_close(ls);
        return SOOC_ENOMEM;
    }
    for (int64_t i = 0; i < n; i++) t[i] = sooc_logseq_frame_time(ls, i);
    sooc_seq_source src = {path, n, t, &cal, 0, ls, src_read, src_close};   /* logseq applies max_depth */
    st = sooc_seq_open_source(out, &src);
    sooc_free(t);
    return st;
}
