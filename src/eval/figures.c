/* Pictures: per-view panels, the top-down cognitive map (paper Figure 3), training curves. */
#include "sooc3d/eval.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define GREY SOOC_RGB(90, 90, 90)

static uint8_t to_u8(float v) {
    if (!(v > 0.f)) return 0;
    if (v >= 1.f) return 255;
    return (uint8_t)lrintf(v * 255.f);
}

/* ------------------------------------------------------------------ panel */

void sooc_panel_opts_default(sooc_panel_opts *o) {
    memset(o, 0, sizeof *o);
    o->scale = 2;
    o->d_clip = 8.0;
    o->max_components = 8;
}

static void put(sooc_image *im, size_t p, uint32_t c) {
    uint8_t *d = (uint8_t *)im->data + 3 * p;
    d[0] = (uint8_t)(c >> 16); d[1] = (uint8_t)(c >> 8); d[2] = (uint8_t)c;
}

sooc_status sooc_eval_panel(sooc_image *out, const sooc_frame *gt, const sooc_render_out *r,
                            const sooc_panel_opts *opts) {
    sooc_panel_opts od;
    if (!opts) { sooc_panel_opts_default(&od); opts = &od; }
    if (!r || !r->rgb || !r->depth || !r->label) return sooc_seterr(SOOC_EINVAL, "panel: render output missing");
    int W = r->width, H = r->height;
    if (gt && (gt->width != W || gt->height != H))
        return sooc_seterr(SOOC_EINVAL, "panel: GT %dx%d vs render %dx%d", gt->width, gt->height, W, H);
    size_t P = (size_t)W * H;
    enum { MAXT = 8 + 64 };
    sooc_image tiles[MAXT];
    const sooc_image *tp[MAXT];
    const char *labels[MAXT];
    char names[MAXT][32];
    memset(tiles, 0, sizeof tiles);
    int nt = 0;
    sooc_status st = SOOC_OK;
#define NEW_TILE(name)                                                                 \
    do {                                                                               \
        if ((st = sooc_image_alloc(&tiles[nt], W, H, SOOC_PIX_RGB8))) goto done;       \
        snprintf(names[nt], sizeof names[nt], "%s", name);                             \
    } while (0)
    if (gt && gt->rgb) {
        NEW_TILE("GT");
        memcpy(tiles[nt].data, gt->rgb, P * 3);
        nt++;
    }
    NEW_TILE("recon");
    for (size_t p = 0; p < 3 * P; p++) ((uint8_t *)tiles[nt].data)[p] = to_u8(r->rgb[p]);
    nt++;
    NEW_TILE("seg");
    for (size_t p = 0; p < P; p++) {
        int k = r->label[p];
        uint32_t id = k < 0 ? 0u : (opts->comp_ids && k < r->n_comp ? opts->comp_ids[k] : (uint32_t)k);
        put(&tiles[nt], p, k < 0 ? SOOC_RGB(0, 0, 0) : k == 0 ? GREY : sooc_cmap_id(id));
    }
    nt++;
    if (gt && gt->instance) {
        NEW_TILE("GT seg");
        for (size_t p = 0; p < P; p++)
            put(&tiles[nt], p, gt->instance[p] == 0 ? GREY : sooc_cmap_id(gt->instance[p]));
        nt++;
    }
    if ((st = sooc_image_from_depth(&tiles[nt], r->depth, W, H, 0.0, opts->d_clip))) goto done;
    snprintf(names[nt++], 32, "depth");
    if (gt && gt->depth) {
        if ((st = sooc_image_from_depth(&tiles[nt], gt->depth, W, H, 0.0, opts->d_clip))) goto done;
        snprintf(names[nt++], 32, "GT depth");
    }
    if (r->uncert) {
        NEW_TILE("");
        float mx = 0.f;
        for (size_t p = 0; p < P; p++) if (r->uncert[p] > mx) mx = r->uncert[p];
        for (size_t p = 0; p < P; p++) put(&tiles[nt], p, sooc_cmap_viridis(mx > 0 ? r->uncert[p] / mx : 0.0));
        snprintf(names[nt], 32, "unc<=%.3f", (double)mx);
        nt++;
    }
    if (r->comp_rgb && r->comp_alpha) {
        int nk = r->n_comp < opts->max_components ? r->n_comp : opts->max_components;
        for (int k = 0; k < nk && nt < MAXT; k++) {
            /* skip empty object components */
            double asum = 0;
            for (size_t p = 0; p < P; p++) asum += r->comp_alpha[k * P + p];
            if (k > 0 && asum < 0.5) continue;
            NEW_TILE("");
            for (size_t p = 0; p < 3 * P; p++) ((uint8_t *)tiles[nt].data)[p] = to_u8(r->comp_rgb[k * P * 3 + p]);
            uint32_t id = opts->comp_ids && k < r->n_comp ? opts->comp_ids[k] : (uint32_t)k;
            if (k == 0) snprintf(names[nt], 32, "layout");
            else snprintf(names[nt], 32, "#%u", id);
            nt++;
        }
    }
    for (int i = 0; i < nt; i++) { tp[i] = &tiles[i]; labels[i] = names[i]; }
    st = sooc_image_contact_sheet(out, tp, labels, nt, nt, opts->scale > 0 ? opts->scale : 1, opts->title);
done:
#undef NEW_TILE
    for (int i = 0; i < MAXT; i++) sooc_image_free(&tiles[i]);
    return st;
}

/* -------------------------------------------------------------- top-down */

void sooc_topdown_opts_default(sooc_topdown_opts *o) {
    memset(o, 0, sizeof *o);
    o->px_per_m = 40.0;
    o->d_clip = 8.0;
    o->min_presence = 0.5f;
}

typedef struct view2d { double x0, z0, s; int w, h; } view2d;
static int px(const view2d *v, double x) { return (int)lround((x - v->x0) * v->s); }
static int pz(const view2d *v, double z) { return (int)lround((z - v->z0) * v->s); }

static void grow(double *b, double x, double z) {
    if (x < b[0]) b[0] = x;
    if (x > b[1]) b[1] = x;
    if (z < b[2]) b[2] = z;
    if (z > b[3]) b[3] = z;
}

/* in the horizontal field of view of camera T_wc and within d_clip (planar) */
static int in_view(const double T_wc[16], const sooc_intrinsics *K, double d_clip, double x, double z,
                   double y) {
    double T_cw[16], p[3], w[3] = {x, y, z}, u, v;
    sooc_se3_inverse(T_cw, T_wc);
    sooc_se3_apply(p, T_cw, w);
    if (p[2] <= 0 || p[2] > d_clip) return 0;
    if (!sooc_cam_project(K, p, &u, &v)) return 0;
    return u >= 0 && u < K->width;
}

/* rotated rectangle outline (or filled via dense lines) on the floor */
static void draw_box(sooc_image *im, const view2d *v, double x, double z, double yaw, double sx, double sz,
                     uint32_t c, int thick, int filled) {
    double R[9];
    sooc_m3_rot_y(R, yaw);
    double cs[4][2] = {{-sx / 2, -sz / 2}, {sx / 2, -sz / 2}, {sx / 2, sz / 2}, {-sx / 2, sz / 2}};
    int X[4], Z[4];
    for (int i = 0; i < 4; i++) {
        double lx = cs[i][0], lz = cs[i][1];
        double wx = x + R[0] * lx + R[2] * lz, wz = z + R[6] * lx + R[8] * lz;
        X[i] = px(v, wx);
        Z[i] = pz(v, wz);
    }
    if (filled) {
        int n = (int)(fmax(sx, sz) * v->s) + 2;
        for (int i = 0; i <= n; i++) {
            double f = (double)i / n;
            int ax = (int)lround(X[0] + f * (X[3] - X[0])), az = (int)lround(Z[0] + f * (Z[3] - Z[0]));
            int bx = (int)lround(X[1] + f * (X[2] - X[1])), bz = (int)lround(Z[1] + f * (Z[2] - Z[1]));
            sooc_draw_line(im, ax, az, bx, bz, c, 2);
        }
    }
    for (int i = 0; i < 4; i++) sooc_draw_line(im, X[i], Z[i], X[(i + 1) % 4], Z[(i + 1) % 4], c, thick);
}

static void draw_frustum(sooc_image *im, const view2d *v, const double T_wc[16], const sooc_intrinsics *K,
                         double len, uint32_t c, int thick) {
    double o[3] = {T_wc[3], T_wc[7], T_wc[11]}, pts[2][3];
    for (int s = 0; s < 2; s++) {   /* image edges at the principal row, planar depth len */
        double u = s ? K->width : 0.0, d[3] = {(u - K->cx) / K->fx, 0.0, 1.0}, wd[3];
        sooc_se3_rotate(wd, T_wc, d);
        pts[s][0] = o[0] + len * wd[0];
        pts[s][2] = o[2] + len * wd[2];
    }
    int ox = px(v, o[0]), oz = pz(v, o[2]);
    sooc_draw_line(im, ox, oz, px(v, pts[0][0]), pz(v, pts[0][2]), c, thick);
    sooc_draw_line(im, ox, oz, px(v, pts[1][0]), pz(v, pts[1][2]), c, thick);
    sooc_draw_line(im, px(v, pts[0][0]), pz(v, pts[0][2]), px(v, pts[1][0]), pz(v, pts[1][2]), c, thick);
}

static sooc_status fit_window(const sooc_topdown_step *steps, int n_steps, const sooc_fig_gt *gt, int n_gt,
                              const sooc_topdown_opts *o, view2d *v) {
    double b[4] = {1e300, -1e300, 1e300, -1e300};
    if (o->xmin != 0 || o->xmax != 0 || o->zmin != 0 || o->zmax != 0) {
        b[0] = o->xmin; b[1] = o->xmax; b[2] = o->zmin; b[3] = o->zmax;
    } else {
        for (int i = 0; i < n_steps; i++) {
            grow(b, steps[i].T_wc[3], steps[i].T_wc[11]);
            for (size_t j = 0; j < steps[i].n_entries; j++) grow(b, steps[i].entries[j].x, steps[i].entries[j].z);
        }
        for (int i = 0; i < n_gt; i++) grow(b, gt[i].x, gt[i].z);
        b[0] -= 1.5; b[1] += 1.5; b[2] -= 1.5; b[3] += 1.5;
    }
    if (!(b[1] > b[0]) || !(b[3] > b[2])) return sooc_seterr(SOOC_EINVAL, "topdown: empty window");
    double s = o->px_per_m > 0 ? o->px_per_m : 40.0;
    double w = (b[1] - b[0]) * s, h = (b[3] - b[2]) * s;
    if (w * h > 4096.0 * 4096.0) s *= 4096.0 / fmax(w, h);
    v->x0 = b[0]; v->z0 = b[2]; v->s = s;
    v->w = (int)ceil((b[1] - b[0]) * s);
    v->h = (int)ceil((b[3] - b[2]) * s);
    return SOOC_OK;
}

sooc_status sooc_eval_topdown(sooc_image *out, const sooc_topdown_step *steps, int n_steps, int cur,
                              const sooc_fig_gt *gt, int n_gt, const sooc_topdown_opts *o) {
    if (!o || !o->K) return sooc_seterr(SOOC_EINVAL, "topdown: options with intrinsics required");
    if (n_steps < 1 || cur < 0 || cur >= n_steps)
        return sooc_seterr(SOOC_EINVAL, "topdown: step %d of %d", cur, n_steps);
    view2d v;
    sooc_status st = fit_window(steps, n_steps, gt, n_gt, o, &v);
    if (st) return st;
    if ((st = sooc_image_alloc(out, v.w, v.h + 12, SOOC_PIX_RGB8))) return st;
    sooc_draw_fill(out, SOOC_RGB(250, 250, 250));
    /* 1 m grid */
    for (double x = ceil(v.x0); x <= v.x0 + v.w / v.s; x += 1.0)
        sooc_draw_line(out, px(&v, x), 0, px(&v, x), v.h - 1, SOOC_RGB(228, 228, 228), 1);
    for (double z = ceil(v.z0); z <= v.z0 + v.h / v.s; z += 1.0)
        sooc_draw_line(out, 0, pz(&v, z), v.w - 1, pz(&v, z), SOOC_RGB(228, 228, 228), 1);
    /* GT objects: black outlines */
    for (int i = 0; i < n_gt; i++)
        draw_box(out, &v, gt[i].x, gt[i].z, gt[i].yaw, gt[i].size_x, gt[i].size_z, SOOC_RGB(20, 20, 20), 1, 0);
    /* path and frustums */
    for (int i = 0; i <= cur; i++) {
        if (i > 0)
            sooc_draw_line(out, px(&v, steps[i - 1].T_wc[3]), pz(&v, steps[i - 1].T_wc[11]), px(&v, steps[i].T_wc[3]),
                           pz(&v, steps[i].T_wc[11]), SOOC_RGB(150, 150, 220), 1);
        if (i < cur) draw_frustum(out, &v, steps[i].T_wc, o->K, 0.4, SOOC_RGB(180, 180, 230), 1);
    }
    draw_frustum(out, &v, steps[cur].T_wc, o->K, o->d_clip, SOOC_RGB(40, 60, 220), 2);
    /* map entries of the current step */
    const sooc_topdown_step *s = &steps[cur];
    for (size_t j = 0; j < s->n_entries; j++) {
        const sooc_map_entry *e = &s->entries[j];
        if (e->presence < o->min_presence) continue;
        int vis = in_view(s->T_wc, o->K, o->d_clip, e->x, e->z, e->extent[1] > 0 ? e->extent[1] / 2 : 0.3);
        uint32_t c = vis ? sooc_cmap_id((uint32_t)e->id) : SOOC_RGB(170, 170, 170);
        double sx = e->extent[0] > 0 ? e->extent[0] : 0.3, sz = e->extent[2] > 0 ? e->extent[2] : 0.3;
        draw_box(out, &v, e->x, e->z, e->yaw, sx, sz, c, 1, 1);
        /* heading tick */
        double R[9];
        sooc_m3_rot_y(R, e->yaw);
        sooc_draw_line(out, px(&v, e->x), pz(&v, e->z), px(&v, e->x + R[2] * sz * 0.7),
                       pz(&v, e->z + R[8] * sz * 0.7), SOOC_RGB(0, 0, 0), 1);
        char lab[24];
        snprintf(lab, sizeof lab, "%llu", (unsigned long long)e->id);
        sooc_draw_text(out, px(&v, e->x) + 4, pz(&v, e->z) + 4, lab, vis ? SOOC_RGB(0, 0, 0) : SOOC_RGB(150, 150, 150),
                       SOOC_DRAW_NOBG, 1);
    }
    char cap[160];
    snprintf(cap, sizeof cap, "%s step %d/%d  entries %zu  1 m grid", o->title ? o->title : "map", cur + 1, n_steps,
             s->n_entries);
    sooc_draw_rect(out, 0, v.h, v.w, 12, SOOC_RGB(255, 255, 255), 0);
    sooc_draw_text(out, 2, v.h + 2, cap, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
    return SOOC_OK;
}

sooc_status sooc_eval_topdown_sequence(const char *dir, const sooc_topdown_step *steps, int n_steps,
                                       const sooc_fig_gt *gt, int n_gt, const sooc_topdown_opts *o) {
    if (n_steps < 1) return sooc_seterr(SOOC_EINVAL, "topdown: no steps");
    sooc_status st = sooc_mkdirs(dir);
    if (st) return st;
    sooc_topdown_opts oo = *o;
    if (!(oo.xmin != 0 || oo.xmax != 0 || oo.zmin != 0 || oo.zmax != 0)) {
        /* one window for the whole sequence */
        view2d v;
        if ((st = fit_window(steps, n_steps, gt, n_gt, o, &v))) return st;
        oo.xmin = v.x0; oo.xmax = v.x0 + v.w / v.s; oo.zmin = v.z0; oo.zmax = v.z0 + v.h / v.s;
        oo.px_per_m = v.s;
    }
    enum { SHEET = 24 };
    int ns = n_steps < SHEET ? n_steps : SHEET;
    sooc_image img = {0}, sheet_tiles[SHEET];
    memset(sheet_tiles, 0, sizeof sheet_tiles);
    const sooc_image *tp[SHEET];
    char names[SHEET][24];
    const char *labels[SHEET];
    int next = 0;
    for (int i = 0; i < n_steps && !st; i++) {
        st = sooc_eval_topdown(&img, steps, n_steps, i, gt, n_gt, &oo);
        if (st) break;
        char path[4096], name[64];
        snprintf(name, sizeof name, "cogmap_%04d.png", i);
        if ((st = sooc_path_join(path, sizeof path, dir, name))) break;
        if ((st = sooc_png_write(path, &img, -1))) break;
        /* evenly spaced sheet tiles, always including the last step */
        int want = ns == 1 ? 0 : (int)((long)next * (n_steps - 1) / (ns - 1));
        if (next < ns && i == want) {
            st = sooc_image_copy(&sheet_tiles[next], &img);
            snprintf(names[next], sizeof names[next], "step %d", i + 1);
            tp[next] = &sheet_tiles[next];
            labels[next] = names[next];
            next++;
        }
    }
    if (!st) {
        char path[4096];
        sooc_image sheet = {0};
        int cols = next <= 4 ? next : (next <= 9 ? 3 : 4);
        st = sooc_image_contact_sheet(&sheet, tp, labels, next, cols > 0 ? cols : 1, 1, oo.title);
        if (!st) st = sooc_path_join(path, sizeof path, dir, "cogmap_sheet.png");
        if (!st) st = sooc_png_write(path, &sheet, -1);
        sooc_image_free(&sheet);
    }
    for (int i = 0; i < SHEET; i++) sooc_image_free(&sheet_tiles[i]);
    sooc_image_free(&img);
    return st;
}

/* ------------------------------------------------------------ training curves */

#define MAXCOL 32
sooc_status sooc_eval_plot_csv(const char *csv_path, const char *png_path, const char *title) {
    void *buf = NULL;
    size_t nbytes = 0;
    sooc_status st = sooc_file_read_all(csv_path, (size_t)1 << 30, &buf, &nbytes);
    if (st) return st;
    char *txt = buf, *save = NULL;
    char *line = strtok_r(txt, "\n", &save);
    if (!line) { sooc_free(buf); return sooc_seterr(SOOC_EFORMAT, "%s: empty CSV", csv_path); }
    char *names[MAXCOL];
    int nc = 0;
    for (char *c = line;;) {
        char *comma = strchr(c, ',');
        if (comma) *comma = 0;
        size_t L = strlen(c);
        while (L && (c[L - 1] == '\r' || c[L - 1] == ' ')) c[--L] = 0;
        while (*c == ' ') c++;
        if (nc < MAXCOL) names[nc++] = c;
        if (!comma) break;
        c = comma + 1;
    }
    int xcol = -1;
    for (int i = 0; i < nc; i++) if (!strcmp(names[i], "step")) xcol = i;
    size_t cap = 1024, nr = 0;
    double *val = sooc_malloc(cap * MAXCOL * sizeof(double));
    if (!val) { sooc_free(buf); return sooc_seterr(SOOC_ENOMEM, "plot: out of memory"); }
    int lineno = 1;
    while ((line = strtok_r(NULL, "\n", &save))) {
        lineno++;
        if (nr == cap) {
            double *nv = sooc_realloc(val, cap * 2 * MAXCOL * sizeof(double));
            if (!nv) { st = sooc_seterr(SOOC_ENOMEM, "plot: out of memory"); goto out; }
            val = nv;
            cap *= 2;
        }
        char *c = line;
        for (int i = 0; i < nc; i++) {
            char *end;
            double x = strtod(c, &end);
            val[nr * MAXCOL + i] = end == c ? NAN : x;
            char *comma = strchr(c, ',');
            if (!comma) { for (int j = i + 1; j < nc; j++) val[nr * MAXCOL + j] = NAN; break; }
            c = comma + 1;
        }
        nr++;
    }
    if (nr == 0) { st = sooc_seterr(SOOC_EFORMAT, "%s: no data rows", csv_path); goto out; }
    {
        const int PW = 300, PH = 170, ML = 46, MB = 14, MT = 14;
        sooc_image tiles[MAXCOL];
        const sooc_image *tp[MAXCOL];
        const char *labels[MAXCOL];
        char lab[MAXCOL][96];
        memset(tiles, 0, sizeof tiles);
        int nt = 0;
        double x0 = 1e300, x1 = -1e300;
        for (size_t r = 0; r < nr; r++) {
            double x = xcol >= 0 ? val[r * MAXCOL + xcol] : (double)r;
            if (isfinite(x)) { x0 = fmin(x0, x); x1 = fmax(x1, x); }
        }
        if (!(x1 > x0)) x1 = x0 + 1;
        for (int col = 0; col < nc && !st; col++) {
            if (col == xcol) continue;
            double y0 = 1e300, y1 = -1e300, last = NAN;
            int pos = 1, cnt = 0;
            for (size_t r = 0; r < nr; r++) {
                double y = val[r * MAXCOL + col];
                if (!isfinite(y)) continue;
                y0 = fmin(y0, y); y1 = fmax(y1, y); pos &= y > 0; cnt++; last = y;
            }
            if (!cnt) continue;
            int logy = pos && y1 > 100 * y0;
            double a = logy ? log10(y0) : y0, b = logy ? log10(y1) : y1;
            if (!(b > a)) { a -= 0.5; b += 0.5; }
            sooc_image *im = &tiles[nt];
            if ((st = sooc_image_alloc(im, PW, PH, SOOC_PIX_RGB8))) break;
            sooc_draw_fill(im, SOOC_RGB(255, 255, 255));
            int gx0 = ML, gx1 = PW - 6, gy0 = MT, gy1 = PH - MB;
            sooc_draw_rect(im, gx0, gy0, gx1 - gx0 + 1, gy1 - gy0 + 1, SOOC_RGB(160, 160, 160), 1);
            int prevx = 0, prevy = 0, have = 0;
            for (size_t r = 0; r < nr; r++) {
                double x = xcol >= 0 ? val[r * MAXCOL + xcol] : (double)r, y = val[r * MAXCOL + col];
                if (!isfinite(x) || !isfinite(y)) continue;
                double yy = logy ? log10(y) : y;
                int X = gx0 + (int)lround((x - x0) / (x1 - x0) * (gx1 - gx0));
                int Y = gy1 - (int)lround((yy - a) / (b - a) * (gy1 - gy0));
                if (have) sooc_draw_line(im, prevx, prevy, X, Y, SOOC_RGB(30, 90, 200), 1);
                else sooc_draw_pixel(im, X, Y, SOOC_RGB(30, 90, 200));
                prevx = X; prevy = Y; have = 1;
            }
            char t[64];
            snprintf(t, sizeof t, "%.3g", logy ? pow(10, b) : b);
            sooc_draw_text(im, 2, gy0, t, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
            snprintf(t, sizeof t, "%.3g", logy ? pow(10, a) : a);
            sooc_draw_text(im, 2, gy1 - 8, t, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
            snprintf(t, sizeof t, "%.0f", x0);
            sooc_draw_text(im, gx0, gy1 + 3, t, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
            snprintf(t, sizeof t, "%.0f", x1);
            int tw, th;
            sooc_text_size(t, 1, &tw, &th);
            sooc_draw_text(im, gx1 - tw, gy1 + 3, t, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
            snprintf(t, sizeof t, "%s%s", names[col], logy ? " (log)" : "");
            sooc_draw_text(im, gx0 + 2, 3, t, SOOC_RGB(0, 0, 0), SOOC_DRAW_NOBG, 1);
            snprintf(lab[nt], sizeof lab[nt], "%s last %.4g", names[col], last);
            tp[nt] = im;
            labels[nt] = lab[nt];
            nt++;
        }
        if (!st && nt == 0) st = sooc_seterr(SOOC_EFORMAT, "%s: no numeric columns to plot", csv_path);
        if (!st) {
            sooc_image sheet = {0};
            st = sooc_image_contact_sheet(&sheet, tp, labels, nt, nt < 3 ? nt : 3, 1, title);
            if (!st) st = sooc_png_write(png_path, &sheet, -1);
            sooc_image_free(&sheet);
        }
        for (int i = 0; i < MAXCOL; i++) sooc_image_free(&tiles[i]);
    }
out:
    sooc_free(val);
    sooc_free(buf);
    return st;
}
