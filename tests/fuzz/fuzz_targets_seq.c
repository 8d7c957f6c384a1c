/*
 * Fuzz entry points for the sequence readers whose metadata is a file of its
 * own, and for the node's --set values (fuzz_targets.h):
 *   ycb_meta   a YCB-Video folder whose 000001-meta.mat is the input
 *              (libmatio, sooc_seq_open + sooc_seq_read);
 *   apc        an APC folder whose cam.info.txt is the input;
 *   node_set   the input's lines as `sooc3d node --set` values over a valid
 *              launch text (sooc_node_config_parse_sets).
 * The folders live in a per-process temporary directory; their images are
 * written once (4x3 colour and 16-bit depth PNGs).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "fuzz_targets.h"
#include "sooc3d/core.h"
#include "sooc3d/frame.h"
#include "sooc3d/node.h"

static void put(const char *path, const uint8_t *d, size_t n) {
    FILE *f = fopen(path, "wb");
    if (!f) abort();   /* environment problem, not a finding */
    if (n && fwrite(d, 1, n, f) != n) abort();
    if (fclose(f)) abort();
}

static void png(const char *path, int depth16) {
    sooc_image img = {0};
    if (sooc_image_alloc(&img, 4, 3, depth16 ? SOOC_PIX_GRAY16 : SOOC_PIX_RGB8)) abort();
    uint8_t *p = img.data;
    for (size_t i = 0; i < (size_t)sooc_pixfmt_bytes(img.fmt) * 12; i++) p[i] = (uint8_t)(40 + 7 * i);
    if (sooc_png_write(path, &img, 1)) abort();
    sooc_image_free(&img);
}

/* <tmp>/sooc-fuzz-<pid>-<tag>/ with the images of the layout, made once. */
static const char *folder(const char *tag, const char *const *color, const char *const *depth, int n) {
    static char dirs[2][400];
    int k = !strcmp(tag, "apc");
    char *dir = dirs[k];
    if (dir[0]) return dir;
    const char *t = getenv("TMPDIR");
    snprintf(dir, sizeof dirs[k], "%.300s/sooc-fuzz-%ld-%s", t && *t ? t : "/tmp", (long)getpid(), tag);
    mkdir(dir, 0755);
    char p[1200];
    for (int i = 0; i < n; i++) {
        snprintf(p, sizeof p, "%s/%s", dir, color[i]);
        png(p, 0);
        snprintf(p, sizeof p, "%s/%s", dir, depth[i]);
        png(p, 1);
    }
    return dir;
}

static int read_seq(const char *dir, sooc_seq_format fmt) {
    sooc_seq_open_params p;
    sooc_seq_open_params_default(&p);
    p.format = fmt;
    sooc_seq *s = NULL;
    int ok = sooc_seq_open(&s, dir, &p) == SOOC_OK;
    if (ok) {
        sooc_frame f = {0};
        for (int64_t i = 0; i < sooc_seq_count(s) && i < 2; i++) ok &= sooc_seq_read(s, i, &f) == SOOC_OK;
        sooc_frame_free(&f);
    }
    sooc_seq_close(s);
    return ok;
}

int sooc_fuzz_ycb_meta(const uint8_t *d, size_t n) {
    static const char *c[] = {"000001-color.png"}, *z[] = {"000001-depth.png"};
    const char *dir = folder("ycb", c, z, 1);
    char p[1200];
    snprintf(p, sizeof p, "%s/000001-meta.mat", dir);
    put(p, d, n);
    return read_seq(dir, SOOC_SEQ_YCB);
}

int sooc_fuzz_apc(const uint8_t *d, size_t n) {
    static const char *c[] = {"frame-000000.color.png", "frame-000001.color.png"},
                      *z[] = {"frame-000000.depth.png", "frame-000001.depth.png"};
    const char *dir = folder("apc", c, z, 2);
    char p[1200];
    snprintf(p, sizeof p, "%s/cam.info.txt", dir);
    put(p, d, n);
    return read_seq(dir, SOOC_SEQ_APC);
}

int sooc_fuzz_node_set(const uint8_t *d, size_t n) {
    static const char base[] =
        "sensor: {driver: replay, path: /nonexistent, speed: fast}\n"
        "pose: {source: sensor}\nmodel: {path: fake.bin}\n"
        "keyframe: {translation_m: 0.10, rotation_deg: 10}\nshm: {name: fuzz, capacity: 64}\n"
        "map: {db: '', resume: false}\npipeline: {ring_capacity: 4}\n";
    char *text = malloc(n + 1);
    if (!text) abort();
    memcpy(text, d, n);
    text[n] = 0;
    const char *sets[16];
    int ns = 0;
    for (char *q = text, *e; q && ns < 16; q = e ? e + 1 : NULL) {
        e = strchr(q, '\n');
        if (e) *e = 0;
        if (*q) sets[ns++] = q;   /* blank lines are not values */
    }
    static sooc_node_config c;
    int ok = sooc_node_config_parse_sets(&c, base, sizeof base - 1, "fuzz.yaml", sets, ns) == SOOC_OK;
    if (ok) {
        char buf[256];
        (void)sooc_node_config_format(&c, buf, sizeof buf);
    }
    free(text);
    return ok;
}
