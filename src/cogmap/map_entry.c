/* Map entry <-> cognitive-map entry (sooc3d/cogmap.h). */
#include "sooc3d/cogmap.h"

#include <stdio.h>

#include <math.h>
#include <string.h>

void sooc_map_entry_from_cogmap(const sooc_cogmap_entry *c, const float extent[3], sooc_map_entry *e) {
    memset(e, 0, sizeof *e);
    e->id = c->id;
    e->x = c->X;
    e->z = c->Z;
    e->yaw = c->Theta;
    e->sigma_t = exp(0.5 * c->rho_t);
    e->sigma_yaw = exp(0.5 * c->rho_theta);
    e->presence_logit = c->pres_logit;
    e->presence = 1.0f / (1.0f + expf(-c->pres_logit));
    int d = c->dim < 0 ? 0 : c->dim > SOOC_MAP_LATENT_MAX ? SOOC_MAP_LATENT_MAX : c->dim;
    e->latent_dim = d;
    memcpy(e->what_mu, c->what_mu, sizeof(float) * (size_t)d);
    memcpy(e->what_logvar, c->what_logvar, sizeof(float) * (size_t)d);
    if (extent) memcpy(e->extent, extent, sizeof e->extent);
    e->first_seen_ns = c->first_seen_ns;
    e->last_seen_ns = c->last_seen_ns;
    e->obs_count = c->obs_count;
}

void sooc_map_entry_to_cogmap(const sooc_map_entry *e, sooc_cogmap_entry *c) {
    memset(c, 0, sizeof *c);
    c->id = e->id;
    c->X = e->x;
    c->Z = e->z;
    c->Theta = e->yaw;
    c->rho_t = (float)(2.0 * log(e->sigma_t > 1e-12 ? e->sigma_t : 1e-12));
    c->rho_theta = (float)(2.0 * log(e->sigma_yaw > 1e-12 ? e->sigma_yaw : 1e-12));
    c->pres_logit = e->presence_logit;
    int d = e->latent_dim < 0 ? 0 : e->latent_dim > SOOC_COGMAP_DIM_MAX ? SOOC_COGMAP_DIM_MAX : e->latent_dim;
    c->dim = d;
    memcpy(c->what_mu, e->what_mu, sizeof(float) * (size_t)d);
    memcpy(c->what_logvar, e->what_logvar, sizeof(float) * (size_t)d);
    c->first_seen_ns = e->first_seen_ns;
    c->last_seen_ns = e->last_seen_ns;
    c->obs_count = e->obs_count ? e->obs_count : 1;
    c->last_view = -1;
}

int sooc_map_entry_planner_cov(const sooc_map_entry *e, double cov[4]) {
    const sooc_map_geometry *g = &e->geom;
    if (g->cov_xz[0] > 0 && g->cov_xz[2] > 0) {
        cov[0] = g->cov_xz[0], cov[1] = g->cov_xz[1], cov[2] = g->cov_xz[2];
        cov[3] = g->var_yaw > SOOC_MAP_YAW_VAR_MAX ? SOOC_MAP_YAW_VAR_MAX : g->var_yaw;   /* NaN stays NaN */
        return 1;
    }
    cov[0] = cov[2] = e->sigma_t * e->sigma_t, cov[1] = 0;
    cov[3] = e->sigma_yaw * e->sigma_yaw;
    if (cov[3] > SOOC_MAP_YAW_VAR_MAX) cov[3] = SOOC_MAP_YAW_VAR_MAX;
    return 0;
}

void sooc_map_entry_planner_sigmas(const sooc_map_entry *e, double *sigma_t, double *sigma_yaw) {
    double cov[4];
    sooc_map_entry_planner_cov(e, cov);
    *sigma_t = sqrt(cov[0]);
    *sigma_yaw = sqrt(cov[3]);
}

double sooc_map_entry_height(const sooc_map_entry *e) {
    return (e->geom.flags & SOOC_GEOM_TIGHT) ? 2.0 * e->geom.centre[1] : (double)e->extent[1];
}

const char *sooc_map_entry_box_quality(const sooc_map_geometry *g, char *buf, size_t cap) {
    static const struct { uint32_t bit; const char *word; } w[] = {
        {SOOC_GEOM_TIGHT, "tight"}, {SOOC_GEOM_EMPTY, "empty"}, {SOOC_GEOM_CLIPPED, "clipped"},
        {SOOC_GEOM_FAINT, "faint"}, {SOOC_GEOM_SYMMETRIC, "symmetric"}, {SOOC_GEOM_SURFACE, "surface"}};
    size_t n = 0;
    if (cap) buf[0] = 0;
    for (size_t i = 0; i < sizeof w / sizeof *w; i++)
        if ((g->flags & w[i].bit) && n < cap) n += (size_t)snprintf(buf + n, cap - n, "%s%s", n ? "," : "", w[i].word);
    if (!n && cap) snprintf(buf, cap, "not computed");
    return buf;
}

void sooc_map_entry_box(const sooc_map_entry *e, double centre[3], double *yaw, float ext[3]) {
    centre[0] = e->x;
    centre[1] = (e->geom.flags & SOOC_GEOM_TIGHT) ? e->geom.centre[1] : 0.5 * e->extent[1];   /* on the floor */
    centre[2] = e->z;
    *yaw = e->yaw;
    memcpy(ext, e->extent, 3 * sizeof *ext);
}
