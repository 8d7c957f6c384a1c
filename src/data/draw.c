/* Drawing on RGB8 images: primitives, a 5x7 bitmap font, colour maps and
 * contact sheets. Everything clips; nothing here fails except allocation. */
#include "sooc3d/core.h"

#include <math.h>
#include <string.h>

static inline void put(sooc_image *img, int x, int y, uint32_t c) {
    if (x < 0 || y < 0 || x >= img->width || y >= img->height || img->fmt != SOOC_PIX_RGB8) return;
    uint8_t *p = (uint8_t *)img->data + ((size_t)y * (size_t)img->width + (size_t)x) * 3;
    p[0] = (uint8_t)(c >> 16);
    p[1] = (uint8_t)(c >> 8);
    p[2] = (uint8_t)c;
}

void sooc_draw_pixel(sooc_image *img, int x, int y, uint32_t rgb) { put(img, x, y, rgb); }

void sooc_draw_fill(sooc_image *img, uint32_t rgb) {
    sooc_draw_rect(img, 0, 0, img->width, img->height, rgb, 0);
}

static void fill_rect(sooc_image *img, int x, int y, int w, int h, uint32_t c) {
    if (img->fmt != SOOC_PIX_RGB8) return;
    int x0 = x < 0 ? 0 : x, y0 = y < 0 ? 0 : y;
    int x1 = x + w > img->width ? img->width : x + w, y1 = y + h > img->height ? img->height : y + h;
    for (int yy = y0; yy < y1; yy++)
        for (int xx = x0; xx < x1; xx++) put(img, xx, yy, c);
}

void sooc_draw_rect(sooc_image *img, int x, int y, int w, int h, uint32_t rgb, int t) {
    if (w <= 0 || h <= 0) return;
    if (t <= 0) { fill_rect(img, x, y, w, h, rgb); return; }
    fill_rect(img, x, y, w, t, rgb);
    fill_rect(img, x, y + h - t, w, t, rgb);
    fill_rect(img, x, y, t, h, rgb);
    fill_rect(img, x + w - t, y, t, h, rgb);
}

void sooc_draw_line(sooc_image *img, int x0, int y0, int x1, int y1, uint32_t rgb, int t) {
    if (t < 1) t = 1;
    int dx = x1 > x0 ? x1 - x0 : x0 - x1, sx = x0 < x1 ? 1 : -1;
    int dy = y1 > y0 ? y0 - y1 : y1 - y0, sy = y0 < y1 ? 1 : -1;
    int err = dx + dy;
    /* bound the work for absurd coordinates */
    long steps = 0, maxsteps = 4L * (img->width + img->height) + 8L * (dx - dy);
    for (;;) {
        if (t == 1) put(img, x0, y0, rgb);
        else fill_rect(img, x0 - t / 2, y0 - t / 2, t, t, rgb);
        if ((x0 == x1 && y0 == y1) || ++steps > maxsteps) break;
        int e2 = 2 * err;
        if (e2 >= dy) { err += dy; x0 += sx; }
        if (e2 <= dx) { err += dx; y0 += sy; }
    }
}

void sooc_draw_circle(sooc_image *img, int cx, int cy, int r, uint32_t rgb, int filled) {
    if (r < 0) return;
    if (filled) {
        for (int dy = -r; dy <= r; dy++) {
            int dx = (int)floor(sqrt((double)r * r - (double)dy * dy + 0.25 * r));
            for (int x = cx - dx; x <= cx + dx; x++) put(img, x, cy + dy, rgb);
        }
        return;
    }
    int x = r, y = 0, err = 1 - r;
    while (x >= y) {
        put(img, cx + x, cy + y, rgb); put(img, cx + y, cy + x, rgb);
        put(img, cx - y, cy + x, rgb); put(img, cx - x, cy + y, rgb);
        put(img, cx - x, cy - y, rgb); put(img, cx - y, cy - x, rgb);
        put(img, cx + y, cy - x, rgb); put(img, cx + x, cy - y, rgb);
        y++;
        if (err < 0) err += 2 * y + 1;
        else { x--; err += 2 * (y - x) + 1; }
    }
}

/* Classic 5x7 font, ASCII 32..126, column-major, bit 0 = top row. */
static const uint8_t g_font5x7[95][5] = {
    {0x00,0x00,0x00,0x00,0x00},{0x00,0x00,0x5F,0x00,0x00},{0x00,0x07,0x00,0x07,0x00},
    {0x14,0x7F,0x14,0x7F,0x14},{0x24,0x2A,0x7F,0x2A,0x12},{0x23,0x13,0x08,0x64,0x62},
    {0x36,0x49,0x55,0x22,0x50},{0x00,0x05,0x03,0x00,0x00},{0x00,0x1C,0x22,0x41,0x00},
    {0x00,0x41,0x22,0x1C,0x00},{0x08,0x2A,0x1C,0x2A,0x08},{0x08,0x08,0x3E,0x08,0x08},
    {0x00,0x50,0x30,0x00,0x00},{0x08,0x08,0x08,0x08,0x08},{0x00,0x60,0x60,0x00,0x00},
    {0x20,0x10,0x08,0x04,0x02},{0x3E,0x51,0x49,0x45,0x3E},{0x00,0x42,0x7F,0x40,0x00},
    {0x42,0x61,0x51,0x49,0x46},{0x21,0x41,0x45,0x4B,0x31},{0x18,0x14,0x12,0x7F,0x10},
    {0x27,0x45,0x45,0x45,0x39},{0x3C,0x4A,0x49,0x49,0x30},{0x01,0x71,0x09,0x05,0x03},
    {0x36,0x49,0x49,0x49,0x36},{0x06,0x49,0x49,0x29,0x1E},{0x00,0x36,0x36,0x00,0x00},
    {0x00,0x56,0x36,0x00,0x00},{0x08,0x14,0x22,0x41,0x00},{0x14,0x14,0x14,0x14,0x14},
    {0x00,0x41,0x22,0x14,0x08},{0x02,0x01,0x51,0x09,0x06},{0x32,0x49,0x79,0x41,0x3E},
    {0x7E,0x11,0x11,0x11,0x7E},{0x7F,0x49,0x49,0x49,0x36},{0x3E,0x41,0x41,0x41,0x22},
    {0x7F,0x41,0x41,0x22,0x1C},{0x7F,0x49,0x49,0x49,0x41},{0x7F,0x09,0x09,0x01,0x01},
    {0x3E,0x41,0x41,0x51,0x32},{0x7F,0x08,0x08,0x08,0x7F},{0x00,0x41,0x7F,0x41,0x00},
    {0x20,0x40,0x41,0x3F,0x01},{0x7F,0x08,0x14,0x22,0x41},{0x7F,0x40,0x40,0x40,0x40},
    {0x7F,0x02,0x04,0x02,0x7F},{0x7F,0x04,0x08,0x10,0x7F},{0x3E,0x41,0x41,0x41,0x3E},
    {0x7F,0x09,0x09,0x09,0x06},{0x3E,0x41,0x51,0x21,0x5E},{0x7F,0x09,0x19,0x29,0x46},
    {0x46,0x49,0x49,0x49,0x31},{0x01,0x01,0x7F,0x01,0x01},{0x3F,0x40,0x40,0x40,0x3F},
    {0x1F,0x20,0x40,0x20,0x1F},{0x7F,0x20,0x18,0x20,0x7F},{0x63,0x14,0x08,0x14,0x63},
    {0x03,0x04,0x78,0x04,0x03},{0x61,0x51,0x49,0x45,0x43},{0x00,0x00,0x7F,0x41,0x41},
    {0x02,0x04,0x08,0x10,0x20},{0x41,0x41,0x7F,0x00,0x00},{0x04,0x02,0x01,0x02,0x04},
    {0x40,0x40,0x40,0x40,0x40},{0x00,0x01,0x02,0x04,0x00},{0x20,0x54,0x54,0x54,0x78},
    {0x7F,0x48,0x44,0x44,0x38},{0x38,0x44,0x44,0x44,0x20},{0x38,0x44,0x44,0x48,0x7F},
    {0x38,0x54,0x54,0x54,0x18},{0x08,0x7E,0x09,0x01,0x02},{0x08,0x14,0x54,0x54,0x3C},
    {0x7F,0x08,0x04,0x04,0x78},{0x00,0x44,0x7D,0x40,0x00},{0x20,0x40,0x44,0x3D,0x00},
    {0x00,0x7F,0x10,0x28,0x44},{0x00,0x41,0x7F,0x40,0x00},{0x7C,0x04,0x18,0x04,0x78},
    {0x7C,0x08,0x04,0x04,0x78},{0x38,0x44,0x44,0x44,0x38},{0x7C,0x14,0x14,0x14,0x08},
    {0x08,0x14,0x14,0x18,0x7C},{0x7C,0x08,0x04,0x04,0x08},{0x48,0x54,0x54,0x54,0x20},
    {0x04,0x3F,0x44,0x40,0x20},{0x3C,0x40,0x40,0x20,0x7C},{0x1C,0x20,0x40,0x20,0x1C},
    {0x3C,0x40,0x30,0x40,0x3C},{0x44,0x28,0x10,0x28,0x44},{0x0C,0x50,0x50,0x50,0x3C},
    {0x44,0x64,0x54,0x4C,0x44},{0x00,0x08,0x36,0x41,0x00},{0x00,0x00,0x7F,0x00,0x00},
    {0x00,0x41,0x36,0x08,0x00},{0x08,0x04,0x08,0x10,0x08},
};

void sooc_text_size(const char *text, int scale, int *w, int *h) {
    if (scale < 1) scale = 1;
    int lines = 1, cur = 0, best = 0;
    for (const char *c = text; c && *c; c++) {
        if (*c == '\n') { lines++; cur = 0; continue; }
        cur++;
        if (cur > best) best = cur;
    }
    if (w) *w = best * 6 * scale;
    if (h) *h = lines * 8 * scale;
}

void sooc_draw_text(sooc_image *img, int x, int y, const char *text, uint32_t fg, uint32_t bg,
                    int scale) {
    if (!text) return;
    if (scale < 1) scale = 1;
    int cx = x, cy = y;
    for (const unsigned char *c = (const unsigned char *)text; *c; c++) {
        if (*c == '\n') { cx = x; cy += 8 * scale; continue; }
        int g = (*c >= 32 && *c <= 126) ? *c - 32 : '?' - 32;
        if (bg != SOOC_DRAW_NOBG) fill_rect(img, cx, cy, 6 * scale, 8 * scale, bg);
        for (int col = 0; col < 5; col++) {
            uint8_t bits = g_font5x7[g][col];
            for (int row = 0; row < 7; row++)
                if (bits & (1u << row))
                    fill_rect(img, cx + col * scale, cy + row * scale, scale, scale, fg);
        }
        cx += 6 * scale;
    }
}

void sooc_draw_blit(sooc_image *dst, const sooc_image *src, int x, int y, int scale) {
    if (!src || !src->data || dst->fmt != SOOC_PIX_RGB8) return;
    if (scale < 1) scale = 1;
    for (int sy = 0; sy < src->height; sy++)
        for (int sx = 0; sx < src->width; sx++) {
            size_t i = (size_t)sy * (size_t)src->width + (size_t)sx;
            uint32_t c;
            if (src->fmt == SOOC_PIX_RGB8) {
                const uint8_t *p = (const uint8_t *)src->data + 3 * i;
                c = SOOC_RGB(p[0], p[1], p[2]);
            } else if (src->fmt == SOOC_PIX_GRAY8) {
                uint8_t v = ((const uint8_t *)src->data)[i];
                c = SOOC_RGB(v, v, v);
            } else {
                uint8_t v = (uint8_t)(((const uint16_t *)src->data)[i] >> 8);
                c = SOOC_RGB(v, v, v);
            }
            if (scale == 1) put(dst, x + sx, y + sy, c);
            else fill_rect(dst, x + sx * scale, y + sy * scale, scale, scale, c);
        }
}

/* ------------------------------------------------------------ colour maps */

static uint32_t pack01(double r, double g, double b) {
    r = r < 0 ? 0 : r > 1 ? 1 : r;
    g = g < 0 ? 0 : g > 1 ? 1 : g;
    b = b < 0 ? 0 : b > 1 ? 1 : b;
    return SOOC_RGB((int)lround(r * 255), (int)lround(g * 255), (int)lround(b * 255));
}

uint32_t sooc_cmap_turbo(double x) {
    if (!(x >= 0)) x = 0;
    if (x > 1) x = 1;
    /* Polynomial fit by Google (turbo colormap, Apache-2.0 shader). */
    double r = 0.13572138 + x * (4.61539260 + x * (-42.66032258 + x * (132.13108234 + x * (-152.94239396 + x * 59.28637943))));
    double g = 0.09140261 + x * (2.19418839 + x * (4.84296658 + x * (-14.18503333 + x * (4.27729857 + x * 2.82956604))));
    double b = 0.10667330 + x * (12.64194608 + x * (-60.58204836 + x * (110.36276771 + x * (-89.90310912 + x * 27.34824973))));
    return pack01(r, g, b);
}

uint32_t sooc_cmap_viridis(double t) {
    if (!(t >= 0)) t = 0;
    if (t > 1) t = 1;
    static const double c[7][3] = {
        {0.2777273272234177, 0.005407344544966578, 0.3340998053353061},
        {0.1050930431085774, 1.404613529898575, 1.384590162594685},
        {-0.3308618287255563, 0.214847559468213, 0.09509516302823659},
        {-4.634230498983486, -5.799100973351585, -19.33244095627987},
        {6.228269936347081, 14.17993336680509, 56.69055260068105},
        {4.776384997670288, -13.74514537774601, -65.35303263337234},
        {-5.435455855934631, 4.645852612178535, 26.3124352495832}};
    double v[3];
    for (int k = 0; k < 3; k++)
        v[k] = c[0][k] + t * (c[1][k] + t * (c[2][k] + t * (c[3][k] + t * (c[4][k] + t * (c[5][k] + t * c[6][k])))));
    return pack01(v[0], v[1], v[2]);
}

static uint32_t hsv(double h, double s, double v) {
    h = fmod(h, 1.0) * 6.0;
    int i = (int)h;
    double f = h - i, p = v * (1 - s), q = v * (1 - s * f), t = v * (1 - s * (1 - f));
    switch (i) {
    case 0: return pack01(v, t, p);
    case 1: return pack01(q, v, p);
    case 2: return pack01(p, v, t);
    case 3: return pack01(p, q, v);
    case 4: return pack01(t, p, v);
    default: return pack01(v, p, q);
    }
}

uint32_t sooc_cmap_id(uint32_t id) {
    if (id == 0) return SOOC_RGB(40, 40, 40);
    double h = fmod(0.08 + (double)id * 0.61803398875, 1.0);
    double s = (id % 3 == 0) ? 0.55 : 0.85;
    double v = (id % 2 == 0) ? 0.80 : 1.0;
    return hsv(h, s, v);
}

sooc_status sooc_image_from_depth(sooc_image *out, const float *depth, int w, int h, double dmin,
                                  double dmax) {
    sooc_status s = sooc_image_alloc(out, w, h, SOOC_PIX_RGB8);
    if (s) return s;
    double span = dmax > dmin ? dmax - dmin : 1.0;
    uint8_t *p = out->data;
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++) {
        float d = depth[i];
        uint32_t c = (d > 0 && isfinite(d)) ? sooc_cmap_turbo((d - dmin) / span) : 0;
        p[3 * i] = (uint8_t)(c >> 16);
        p[3 * i + 1] = (uint8_t)(c >> 8);
        p[3 * i + 2] = (uint8_t)c;
    }
    return SOOC_OK;
}

sooc_status sooc_image_from_ids(sooc_image *out, const uint16_t *ids, int w, int h) {
    sooc_status s = sooc_image_alloc(out, w, h, SOOC_PIX_RGB8);
    if (s) return s;
    uint8_t *p = out->data;
    for (size_t i = 0; i < (size_t)w * (size_t)h; i++) {
        uint32_t c = sooc_cmap_id(ids[i]);
        p[3 * i] = (uint8_t)(c >> 16);
        p[3 * i + 1] = (uint8_t)(c >> 8);
        p[3 * i + 2] = (uint8_t)c;
    }
    return SOOC_OK;
}

sooc_status sooc_image_from_rgb(sooc_image *out, const uint8_t *rgb, int w, int h) {
    sooc_status s = sooc_image_alloc(out, w, h, SOOC_PIX_RGB8);
    if (s) return s;
    memcpy(out->data, rgb, (size_t)w * (size_t)h * 3);
    return SOOC_OK;
}

sooc_status sooc_image_contact_sheet(sooc_image *out, const sooc_image *const *tiles,
                                     const char *const *labels, int n, int ncols, int scale,
                                     const char *title) {
    if (n <= 0 || ncols <= 0) return sooc_seterr(SOOC_EINVAL, "contact sheet: no tiles");
    if (scale < 1) scale = 1;
    int tw = 1, th = 1, lh = 0;
    for (int i = 0; i < n; i++) {
        if (tiles[i] && tiles[i]->data) {
            if (tiles[i]->width > tw) tw = tiles[i]->width;
            if (tiles[i]->height > th) th = tiles[i]->height;
        }
        if (labels && labels[i]) {
            int h;
            sooc_text_size(labels[i], 1, NULL, &h);
            if (h > lh) lh = h;
        }
    }
    const int pad = 4;
    int cw = tw * scale + pad, ch = th * scale + pad + (lh ? lh + 2 : 0);
    int nrows = (n + ncols - 1) / ncols;
    int title_h = 0;
    if (title) {
        sooc_text_size(title, 1, NULL, &title_h);
        title_h += 4;
    }
    sooc_status s = sooc_image_alloc(out, ncols * cw + pad, nrows * ch + pad + title_h, SOOC_PIX_RGB8);
    if (s) return s;
    sooc_draw_fill(out, SOOC_RGB(24, 24, 28));
    if (title) sooc_draw_text(out, pad, 2, title, SOOC_RGB(230, 230, 230), SOOC_DRAW_NOBG, 1);
    for (int i = 0; i < n; i++) {
        int x = pad + (i % ncols) * cw, y = title_h + pad + (i / ncols) * ch;
        if (tiles[i] && tiles[i]->data) sooc_draw_blit(out, tiles[i], x, y, scale);
        if (labels && labels[i])
            sooc_draw_text(out, x, y + th * scale + 2, labels[i], SOOC_RGB(220, 220, 220),
                           SOOC_DRAW_NOBG, 1);
    }
    return SOOC_OK;
}
