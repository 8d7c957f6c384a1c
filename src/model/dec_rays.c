/* The decoder's geometry (model/decoder.h; docs/model.md): the object
 * transform Π(z_where) with its backward, the backward of the Gaussian trick,
 * the decode's noise draws, and a view's rays and samples. */
#include "model/decoder.h"

#include <math.h>
#include <string.h>

/* ---------------------------------------------------------------- Π, trick */

void sooc_mdl_pi(const float x[3], float px, float pz, float th, float h, float xk[3]) {
    float c = cosf(th), s = sinf(th);
    float vx = x[0] - px, vy = x[1] + h, vz = x[2] - pz;
    xk[0] = c * vx - s * vz;
    xk[1] = vy;
    xk[2] = s * vx + c * vz;
}

/* gw = (d/dpx, d/dpz, d/dth) given gxk = dL/dxk (accumulates). */
void sooc_mdl_pi_backward(const float xk[3], float th, const float g[3], float gw[3]) {
    float c = cosf(th), s = sinf(th);
    gw[0] += -(c * g[0] + s * g[2]);
    gw[1] += s * g[0] - c * g[2];
    gw[2] += -xk[2] * g[0] + xk[0] * g[2];
}

void sooc_mdl_gauss_backward(float g, float sig, float zp, const float xk[3], float s, float gxk[3]) {
    float sh = sig * zp, is2 = 1.0f / (s * s);
    gxk[0] += g * sh * (-xk[0] * is2);
    gxk[2] += g * sh * (-xk[2] * is2);
}

/* ---------------------------------------------------------------- noise, rays */

void sooc_mdl_sample_noise(const sooc_model *m, sooc_rng *r, sooc_dec_noise *n) {
    memset(n, 0, sizeof *n);
    const sooc_model_config *c = &m->cfg;
    for (int k = 0; k < c->K; k++) {
        for (int i = 0; i < 3; i++) n->eps_where[k][i] = (float)sooc_rng_normal(r);
        for (int i = 0; i < c->d_what; i++) n->eps_what[k][i] = (float)sooc_rng_normal(r);
        n->logistic[k] = (float)sooc_rng_logistic(r);
    }
    for (int i = 0; i < c->d_layout; i++) n->eps_lay[i] = (float)sooc_rng_normal(r);
}

sooc_status sooc_mdl_rays_alloc(sooc_view_rays *vr, int gw, int gh) {
    memset(vr, 0, sizeof *vr);
    int N = gw * gh;
    vr->N = N;
    vr->gw = gw;
    vr->gh = gh;
    vr->dir = sooc_calloc((size_t)N * 3, sizeof(float));
    vr->rgb = sooc_calloc((size_t)N * 3, sizeof(float));
    vr->depth = sooc_calloc(N, sizeof(float));
    vr->surf = sooc_calloc(N, 1);
    vr->unk = sooc_calloc(N, 1);
    vr->W = sooc_calloc(N, sizeof(float));
    vr->pts = sooc_calloc((size_t)N * 6, sizeof(float));
    if (!vr->dir || !vr->rgb || !vr->depth || !vr->surf || !vr->unk || !vr->W || !vr->pts) {
        sooc_mdl_rays_free(vr);
        return SOOC_ENOMEM;
    }
    return SOOC_OK;
}

void sooc_mdl_rays_free(sooc_view_rays *vr) {
    sooc_free(vr->dir);
    sooc_free(vr->rgb);
    sooc_free(vr->depth);
    sooc_free(vr->surf);
    sooc_free(vr->unk);
    sooc_free(vr->W);
    sooc_free(vr->pts);
    memset(vr, 0, sizeof *vr);
}

sooc_status sooc_mdl_make_rays(const sooc_model *m, const sooc_frame *f, int ox, int oy, sooc_rng *r, sooc_view_rays *vr,
                          const double T_wg[16], double h, double pitch, const double blk_local[2]) {
    const sooc_model_config *c = &m->cfg;
    if (f->width != c->img_w || f->height != c->img_h)
        return sooc_seterr(SOOC_EINVAL, "frame %lld: size %dx%d, model expects %dx%d", (long long)f->index, f->width,
                           f->height, c->img_w, c->img_h);
    int sx = c->img_w / c->ray_w, sy = c->img_h / c->ray_h;
    double Rwg[9], Rwc[9], tt[3], Rgc[9], RwgT[9];
    sooc_se3_to_rt(Rwg, tt, T_wg);
    sooc_se3_to_rt(Rwc, tt, f->T_wc);
    sooc_m3_transpose(RwgT, Rwg);
    sooc_m3_mul(Rgc, RwgT, Rwc);
    /* h, blk_local and the frame's depth are in metres: model units from here on (config.unit_m) */
    float iu = 1.0f / c->unit_m;
    vr->h = (float)h * iu;
    vr->pitch = (float)pitch;
    vr->blk[0] = (float)blk_local[0] * iu;
    vr->blk[1] = (float)-h * iu;
    vr->blk[2] = (float)blk_local[1] * iu;
    float cut = c->air_cut;
    int unk_mode = c->invalid_depth == SOOC_INVALID_DEPTH_UNKNOWN;
    for (int i = 0; i < c->ray_h; i++)
        for (int j = 0; j < c->ray_w; j++) {
            int rr = i * c->ray_w + j, u = j * sx + ox, v = i * sy + oy;
            double dc[3], dg[3];
            double uz = sooc_cam_ray(&f->K, u, v, dc);
            sooc_m3_mulv(dg, Rgc, dc);
            for (int a = 0; a < 3; a++) vr->dir[rr * 3 + a] = (float)dg[a];
            size_t pix = (size_t)v * f->width + u;
            for (int a = 0; a < 3; a++) vr->rgb[rr * 3 + a] = f->rgb[pix * 3 + a] * (1.0f / 255.0f);
            float z = f->depth ? f->depth[pix] : 0.0f;
            int valid = (f->valid ? f->valid[pix] != 0 : 1) && z > 0 && isfinite(z);
            float d = valid ? (float)(z / uz) * iu : 0.0f;
            int surf = valid && d <= c->d_clip && d > c->t_near;
            /* UNKNOWN: a hole (or a reading inside the near plane) says nothing about the ray;
             * a valid depth beyond d_clip still says "no surface up to d_clip" */
            int unk = unk_mode && !surf && !(valid && d > c->d_clip);
            vr->surf[rr] = (uint8_t)surf;
            vr->unk[rr] = (uint8_t)unk;
            vr->depth[rr] = d;
            float *ps = vr->pts + rr * 6, *pa = ps + 3;
            float ta;
            if (surf) {
                float es = c->delta_s * sooc_rng_uniformf(r);
                for (int a = 0; a < 3; a++) ps[a] = (d + es) * vr->dir[rr * 3 + a];
                int near = sooc_rng_uniformf(r) < 0.5f;
                float U = sooc_rng_uniformf(r);
                if (near) {
                    ta = d * (cut + (1 - cut) * U);
                    vr->W[rr] = 2 * (1 - cut) * d;
                } else {
                    ta = d * cut * U;
                    vr->W[rr] = 2 * cut * d;
                }
            } else if (unk) {
                for (int a = 0; a < 3; a++) ps[a] = 0;
                ta = 0;
                vr->W[rr] = 0;
            } else {
                for (int a = 0; a < 3; a++) ps[a] = 0;
                ta = c->d_clip * sooc_rng_uniformf(r);
                vr->W[rr] = c->d_clip;
            }
            for (int a = 0; a < 3; a++) pa[a] = ta * vr->dir[rr * 3 + a];
        }
    return SOOC_OK;
}
