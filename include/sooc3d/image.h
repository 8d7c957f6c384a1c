/*
 * sooc3d images: PNG / PGM / JPEG input and output, and simple drawing for pictures
 * (filled/outlined rectangles, lines, circles, a built-in 5x7 bitmap font,
 * colour maps for depth and ids, contact sheets).
 *
 * Pixel formats: RGB8 (3 bytes per pixel), GRAY8, GRAY16. Pixels are stored
 * row-major, top row first, with no row padding. GRAY16 samples are kept in
 * HOST byte order in memory; the PNG and PGM codecs convert from/to the
 * big-endian order those formats use on disk.
 *
 * Ownership: an image owns `data` (sooc_malloc); release with
 * sooc_image_free. A zero-initialised sooc_image is "empty" and may be passed
 * to any function that fills an image (it is (re)allocated as needed).
 *
 * Thread safety: all functions are reentrant; distinct images may be used
 * from distinct threads.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_IMAGE_H
#define SOOC3D_IMAGE_H

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum sooc_pixfmt {
    SOOC_PIX_NONE = 0,
    SOOC_PIX_GRAY8 = 1,   /* 1 byte per pixel                       */
    SOOC_PIX_GRAY16 = 2,  /* uint16 per pixel, host byte order       */
    SOOC_PIX_RGB8 = 3     /* 3 bytes per pixel, R G B                */
} sooc_pixfmt;

typedef struct sooc_image {
    int width, height;
    sooc_pixfmt fmt;
    void *data;           /* uint8_t* (GRAY8, RGB8) or uint16_t* (GRAY16) */
} sooc_image;

/* Name of a pixel format ("rgb8", "gray8", "gray16", "none"). */
const char *sooc_pixfmt_name(sooc_pixfmt f);
/* Bytes per pixel (0 for NONE). */
int sooc_pixfmt_bytes(sooc_pixfmt f);

/* (Re)allocate `img` as w x h of format fmt, zero-filled. Reuses the buffer
 * when the size and format already match. */
sooc_status sooc_image_alloc(sooc_image *img, int w, int h, sooc_pixfmt fmt);
void sooc_image_free(sooc_image *img);          /* NULL-safe; leaves it empty */
/* Deep copy into dst (reallocated). */
sooc_status sooc_image_copy(sooc_image *dst, const sooc_image *src);

/* --------------------------------------------------------------- codecs */

/* Limits of the readers (PNG and PGM): width and height <= 16384 and at most
 * 256 MiB of decoded pixels; larger files are rejected (EFORMAT, naming the
 * file) before anything is allocated. */
#define SOOC_IMAGE_READ_MAX_DIM 16384
#define SOOC_IMAGE_READ_MAX_BYTES ((size_t)256 << 20)

/* Read a PNG. Gray 1/2/4/8-bit -> GRAY8, gray 16-bit -> GRAY16, RGB or
 * palette -> RGB8 (16-bit colour is reduced to 8 bits), alpha is dropped.
 * Errors name the file: ENOTFOUND (missing), EFORMAT (not a PNG / corrupt). */
sooc_status sooc_png_read(const char *path, sooc_image *out);
/* Read the size and format a PNG would decode to, without decoding pixels. */
sooc_status sooc_png_info(const char *path, int *w, int *h, sooc_pixfmt *fmt);
/* Write a PNG via a temp file + rename (no fsync). `level` is the zlib level
 * 0..9, or -1 for the default (6). Output bytes are deterministic. */
sooc_status sooc_png_write(const char *path, const sooc_image *img, int level);
/* Decode n bytes of PNG in memory (ROS CompressedImage messages) with the
 * reader's conversions and limits; `name` (may be NULL) is used in messages. */
sooc_status sooc_png_decode(const void *buf, size_t n, const char *name, sooc_image *out);
/* Encode to a sooc_malloc'd buffer (*out, *n); the caller frees. */
sooc_status sooc_png_encode(const sooc_image *img, int level, void **out, size_t *n);

/* Read a binary PGM (P5) with maxval <= 255 (-> GRAY8) or 256..65535
 * (-> GRAY16, samples big-endian on disk as the Netpbm spec says). ASCII P2
 * is accepted too. Comments (#) in the header are skipped. */
sooc_status sooc_pgm_read(const char *path, sooc_image *out);
/* Write a binary PGM from GRAY8 or GRAY16 (maxval 255 or 65535). */
sooc_status sooc_pgm_write(const char *path, const sooc_image *img);

/* JPEG through libjpeg-turbo (baseline, progressive, any chroma
 * subsampling, Motion-JPEG frames without Huffman tables). 3-component
 * (YCbCr/RGB) -> RGB8, 1-component -> GRAY8; CMYK is EUNSUPPORTED. Same size
 * limits as PNG. A truncated or corrupt stream (premature end, bad Huffman
 * code, lost sync, bad progression) is EFORMAT "<name>: corrupt JPEG: ..."
 * and `out` holds no partial image that could be mistaken for a good one
 * (its buffer may have been reallocated). libjpeg never prints. */
sooc_status sooc_jpeg_read(const char *path, sooc_image *out);
/* Decode n bytes in memory (V4L2 MJPEG buffers); `name` (may be NULL) is used
 * in messages in place of a path. */
sooc_status sooc_jpeg_decode(const void *buf, size_t n, const char *name, sooc_image *out);
/* Encode RGB8 or GRAY8 at `quality` 1..100 (else 90), 4:2:0, to a sooc_malloc'd
 * buffer; and write a file atomically (temp + rename). */
sooc_status sooc_jpeg_encode(const sooc_image *img, int quality, void **out, size_t *n);
sooc_status sooc_jpeg_write(const char *path, const sooc_image *img, int quality);

/* Read any supported image by content, whatever its extension: PNG
 * signature, "P5"/"P2" (PGM), FF D8 FF (JPEG). */
sooc_status sooc_image_read(const char *path, sooc_image *out);
/* Size and format `path` would decode to, by content (PNG and JPEG read only
 * the header). */
sooc_status sooc_image_info(const char *path, int *w, int *h, sooc_pixfmt *fmt);

/* ------------------------------------------------------------- drawing */
/* All drawing functions work on RGB8 images, clip to the image, and never
 * fail (coordinates may be anywhere). Colours are packed 0xRRGGBB. */

#define SOOC_RGB(r, g, b) ((uint32_t)(((uint32_t)(r) << 16) | ((uint32_t)(g) << 8) | (uint32_t)(b)))

void sooc_draw_fill(sooc_image *img, uint32_t rgb);
void sooc_draw_pixel(sooc_image *img, int x, int y, uint32_t rgb);
/* Rectangle [x, x+w) x [y, y+h); outline of the given thickness, or filled
 * when thickness <= 0. */
void sooc_draw_rect(sooc_image *img, int x, int y, int w, int h, uint32_t rgb, int thickness);
/* Bresenham line, both end points included; thickness >= 1 (square pen). */
void sooc_draw_line(sooc_image *img, int x0, int y0, int x1, int y1, uint32_t rgb, int thickness);
/* Circle of radius r around (cx, cy): filled when `filled`, else 1-px outline. */
void sooc_draw_circle(sooc_image *img, int cx, int cy, int r, uint32_t rgb, int filled);
/* Text in the built-in 5x7 font (ASCII 32..126; others draw as '?'), each
 * glyph cell 6x8 pixels times `scale` (>= 1). '\n' starts a new line. The
 * top-left of the first glyph cell is (x, y). If bg is not SOOC_DRAW_NOBG,
 * the cells are filled with bg first. */
#define SOOC_DRAW_NOBG 0xFFFFFFFFu
void sooc_draw_text(sooc_image *img, int x, int y, const char *text, uint32_t fg, uint32_t bg,
                    int scale);
/* Size in pixels of `text` drawn at `scale` (widest line x number of lines). */
void sooc_text_size(const char *text, int scale, int *w, int *h);
/* Copy src (RGB8, GRAY8 or GRAY16 (>>8)) into dst (RGB8) at (x, y), each
 * source pixel becoming a `scale` x `scale` block (nearest neighbour). */
void sooc_draw_blit(sooc_image *dst, const sooc_image *src, int x, int y, int scale);

/* ---------------------------------------------------------- colour maps */

/* Turbo colour map (Google), t in [0, 1] (clamped). */
uint32_t sooc_cmap_turbo(double t);
/* Viridis-like colour map, t in [0, 1] (clamped). */
uint32_t sooc_cmap_viridis(double t);
/* A distinct colour per id: 0 -> dark grey, others well separated hues
 * (golden-angle hue, alternating value), the same in every run. */
uint32_t sooc_cmap_id(uint32_t id);

/* Colourise a depth map (H*W floats in metres, `stride` floats per row =
 * width when 0) into an RGB8 image with turbo over [dmin, dmax]; depth <= 0
 * or non-finite pixels are black. */
sooc_status sooc_image_from_depth(sooc_image *out, const float *depth, int w, int h, double dmin,
                                  double dmax);
/* Colourise an id map (H*W uint16) with sooc_cmap_id. */
sooc_status sooc_image_from_ids(sooc_image *out, const uint16_t *ids, int w, int h);
/* Wrap RGB8 bytes (H*W*3) into a new image (copied). */
sooc_status sooc_image_from_rgb(sooc_image *out, const uint8_t *rgb, int w, int h);

/* --------------------------------------------------------- contact sheet */

/* A grid of `n` tiles, `ncols` per row, each tile magnified by `scale`
 * (nearest), with its label (may be NULL) printed under it in the built-in
 * font. Cells are sized to the largest tile; the background is dark grey.
 * An optional `title` (may be NULL) is printed on top. Tiles may be RGB8,
 * GRAY8 or GRAY16; NULL tiles leave an empty cell. */
sooc_status sooc_image_contact_sheet(sooc_image *out, const sooc_image *const *tiles,
                                     const char *const *labels, int n, int ncols, int scale,
                                     const char *title);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_IMAGE_H */
