/* The generator's parameters (include/sooc3d/gen.h): defaults, preset and
 * scale names, the room side and view counts of each scale. */
#include "sooc3d/gen.h"

#include <string.h>

void sooc_gen_params_default(sooc_gen_params *p) {
    memset(p, 0, sizeof *p);
    p->preset = SOOC_GEN_UNITY;
    p->scale = SOOC_GEN_S;
    p->seed = 1;
    p->n_scenes = 1;
    p->width = p->height = 64;
    p->n_views = 0;
    p->n_query = -1;
    p->fov_deg = 60;
    p->clip_depth = 8;
    p->density = 0.2;
    p->depth_scale = 2e-4;
    p->write_meshes = 1;
    p->contact_sheet = 1;
}

static const char *g_presets[] = {"unity", "blender", "tabletop"};
static const char *g_scales[] = {"s", "m", "l", "xl"};

sooc_status sooc_gen_preset_parse(const char *s, sooc_gen_preset *out) {
    for (int i = 0; i < 3; i++)
        if (s && !strcmp(s, g_presets[i])) { *out = (sooc_gen_preset)i; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "unknown preset '%s' (unity, blender, tabletop)", s ? s : "");
}
sooc_status sooc_gen_scale_parse(const char *s, sooc_gen_scale *out) {
    for (int i = 0; i < 4; i++)
        if (s && !strcmp(s, g_scales[i])) { *out = (sooc_gen_scale)i; return SOOC_OK; }
    return sooc_seterr(SOOC_EINVAL, "unknown scale '%s' (s, m, l, xl)", s ? s : "");
}
const char *sooc_gen_preset_name(sooc_gen_preset p) { return (unsigned)p < 3 ? g_presets[p] : "?"; }
const char *sooc_gen_scale_name(sooc_gen_scale s) { return (unsigned)s < 4 ? g_scales[s] : "?"; }
double sooc_gen_scale_side(sooc_gen_scale s) {
    static const double side[] = {4, 8, 24, 48};
    return (unsigned)s < 4 ? side[s] : 4;
}
int sooc_gen_default_views(sooc_gen_scale s) {
    static const int v[] = {10, 20, 60, 120};
    return (unsigned)s < 4 ? v[s] : 10;
}

int sooc_gen_views(const sooc_gen_params *p) {
    static const int tt[] = {10, 20, 30};
    if (p->n_views > 0) return p->n_views;
    if (p->preset == SOOC_GEN_TABLETOP) return (unsigned)p->scale < 3 ? tt[p->scale] : 30;
    return sooc_gen_default_views(p->scale);
}
int sooc_gen_noisy(const sooc_gen_params *p) {
    return p->noise == SOOC_GEN_NOISE_KINECT || (p->noise == SOOC_GEN_NOISE_AUTO && p->preset == SOOC_GEN_TABLETOP);
}
