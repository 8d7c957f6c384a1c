/* Binary little-endian PLY for sooc_mesh (include/sooc3d/render.h): written
 * into one buffer and saved atomically; the reader takes what the writer
 * writes and other triangle PLYs with float x y z and optional uchar colour. */
#include "sooc3d/render.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int host_le(void) {
    const uint16_t one = 1;
    return *(const uint8_t *)&one == 1;
}

static void put_u32(unsigned char *w, uint32_t u) {
    if (!host_le()) u = __builtin_bswap32(u);
    memcpy(w, &u, 4);
}

static uint32_t get_u32(const unsigned char *r) {
    uint32_t u;
    memcpy(&u, r, 4);
    return host_le() ? u : __builtin_bswap32(u);
}

sooc_status sooc_mesh_write_ply(const sooc_mesh *m, const char *path, const char *comment) {
    char hdr[1024];
    char com[512] = "";
    if (comment) {   /* one header line: no newlines in a comment */
        snprintf(com, sizeof com, "%s", comment);
        for (char *p = com; *p; p++)
            if (*p == '\n' || *p == '\r') *p = ' ';
    }
    int hl = snprintf(hdr, sizeof hdr,
                      "ply\nformat binary_little_endian 1.0\ncomment %s\nelement vertex %zu\n"
                      "property float x\nproperty float y\nproperty float z\n"
                      "property uchar red\nproperty uchar green\nproperty uchar blue\n"
                      "element face %zu\nproperty list uchar int vertex_indices\nend_header\n",
                      com[0] ? com : "sooc3d mesh", m->n_vert, m->n_tri);
    if (hl < 0 || hl >= (int)sizeof hdr) return sooc_seterr(SOOC_EINVAL, "%s: PLY header too long", path);
    size_t n = (size_t)hl + m->n_vert * 15 + m->n_tri * 13;
    unsigned char *b = sooc_malloc(n ? n : 1), *w = b;
    if (!b) return SOOC_ENOMEM;
    memcpy(w, hdr, (size_t)hl);
    w += hl;
    for (size_t i = 0; i < m->n_vert; i++) {
        for (int k = 0; k < 3; k++) {
            uint32_t u;
            memcpy(&u, &m->xyz[3 * i + k], 4);
            put_u32(w, u);
            w += 4;
        }
        memcpy(w, m->rgb + 3 * i, 3);
        w += 3;
    }
    for (size_t t = 0; t < m->n_tri; t++) {
        *w++ = 3;
        for (int k = 0; k < 3; k++, w += 4) put_u32(w, m->tri[3 * t + k]);
    }
    sooc_status s = sooc_file_write_atomic(path, b, n);
    sooc_free(b);
    if (s) return sooc_adderr(s, "writing %s", path);
    return SOOC_OK;
}

/* ---------------------------------------------------------------- reader */

typedef struct ply_prop {
    char name[32];
    int size;        /* bytes of a scalar, or of the list's items */
    int is_float;    /* float32 scalar                            */
    int list_count;  /* bytes of the list count (0 = not a list) */
} ply_prop;

static int type_size(const char *t, int *is_float) {
    *is_float = 0;
    if (!strcmp(t, "char") || !strcmp(t, "uchar") || !strcmp(t, "int8") || !strcmp(t, "uint8")) return 1;
    if (!strcmp(t, "short") || !strcmp(t, "ushort") || !strcmp(t, "int16") || !strcmp(t, "uint16")) return 2;
    if (!strcmp(t, "int") || !strcmp(t, "uint") || !strcmp(t, "int32") || !strcmp(t, "uint32")) return 4;
    if (!strcmp(t, "float") || !strcmp(t, "float32")) return *is_float = 1, 4;
    if (!strcmp(t, "double") || !strcmp(t, "float64")) return 8;
    return 0;
}

#define PLY_MAXP 24

sooc_status sooc_mesh_read_ply(const char *path, sooc_mesh *out) {
    void *buf = NULL;
    size_t n = 0;
    out->n_vert = out->n_tri = 0;
    sooc_status s = sooc_file_read_all(path, (size_t)4 << 30, &buf, &n);
    if (s) return s;
    const unsigned char *d = buf;
    const char *end = n >= 11 ? strstr((const char *)d, "end_header\n") : NULL;
    if (n < 4 || memcmp(d, "ply\n", 4) || !end) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "%s: not a PLY file (no 'ply' / 'end_header')", path);
    }
    size_t hlen = (size_t)(end - (const char *)d) + 11;
    size_t nv = 0, nf = 0;
    ply_prop vp[PLY_MAXP], fp[PLY_MAXP];
    int nvp = 0, nfp = 0, cur = -1, binle = 0;
    char line[256];
    const char *p = (const char *)d;
    while (p < end) {
        const char *e = memchr(p, '\n', (size_t)(end - p) + 1);
        size_t l = (size_t)(e - p);
        if (l >= sizeof line) l = sizeof line - 1;
        memcpy(line, p, l);
        line[l] = 0;
        p = e + 1;
        char a[32], b[32], c[32], dd[32];
        unsigned long long cnt;
        if (sscanf(line, "format %31s", a) == 1) binle = !strcmp(a, "binary_little_endian");
        else if (sscanf(line, "element %31s %llu", a, &cnt) == 2) {
            cur = !strcmp(a, "vertex") ? 0 : !strcmp(a, "face") ? 1 : 2;
            if (cur == 0) nv = (size_t)cnt;
            if (cur == 1) nf = (size_t)cnt;
            if (cur == 2 && cnt) {
                sooc_free(buf);
                return sooc_seterr(SOOC_EUNSUPPORTED, "%s: element '%s' is not read", path, a);
            }
        } else if (sscanf(line, "property list %31s %31s %31s", a, b, c) == 3) {
            int fl, cs = type_size(a, &fl), is = type_size(b, &fl);
            ply_prop *pp = cur == 0 ? (nvp < PLY_MAXP ? &vp[nvp++] : NULL) : cur == 1 ? (nfp < PLY_MAXP ? &fp[nfp++] : NULL) : NULL;
            if (!pp || !cs || !is) {
                sooc_free(buf);
                return sooc_seterr(SOOC_EFORMAT, "%s: bad header line '%s'", path, line);
            }
            snprintf(pp->name, sizeof pp->name, "%s", c);
            pp->size = is, pp->list_count = cs, pp->is_float = 0;
        } else if (sscanf(line, "property %31s %31s", a, dd) == 2) {
            int fl, sz = type_size(a, &fl);
            ply_prop *pp = cur == 0 ? (nvp < PLY_MAXP ? &vp[nvp++] : NULL) : cur == 1 ? (nfp < PLY_MAXP ? &fp[nfp++] : NULL) : NULL;
            if (!pp || !sz) {
                sooc_free(buf);
                return sooc_seterr(SOOC_EFORMAT, "%s: bad header line '%s'", path, line);
            }
            snprintf(pp->name, sizeof pp->name, "%s", dd);
            pp->size = sz, pp->is_float = fl, pp->list_count = 0;
        }
    }
    if (!binle) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: only binary_little_endian PLY is read", path);
    }
    int ix = -1, iy = -1, iz = -1, ir = -1, ig = -1, ib = -1, vstride = 0, off[PLY_MAXP];
    for (int i = 0; i < nvp; i++) {
        if (vp[i].list_count) {
            sooc_free(buf);
            return sooc_seterr(SOOC_EUNSUPPORTED, "%s: list property in vertices", path);
        }
        off[i] = vstride;
        vstride += vp[i].size;
        const char *nm = vp[i].name;
        if (!strcmp(nm, "x") && vp[i].is_float) ix = i;
        if (!strcmp(nm, "y") && vp[i].is_float) iy = i;
        if (!strcmp(nm, "z") && vp[i].is_float) iz = i;
        if (!strcmp(nm, "red") && vp[i].size == 1) ir = i;
        if (!strcmp(nm, "green") && vp[i].size == 1) ig = i;
        if (!strcmp(nm, "blue") && vp[i].size == 1) ib = i;
    }
    if (ix < 0 || iy < 0 || iz < 0 || (nf && (nfp != 1 || !fp[0].list_count || fp[0].size != 4))) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EUNSUPPORTED, "%s: needs float x y z and faces as one list of int32", path);
    }
    if (nv > (size_t)UINT32_MAX || (n - hlen) / (vstride ? (size_t)vstride : 1) < nv) {
        sooc_free(buf);
        return sooc_seterr(SOOC_EFORMAT, "%s: truncated (%zu vertices declared)", path, nv);
    }
    sooc_mesh m = {0};
    m.xyz = sooc_malloc((nv ? nv : 1) * 3 * sizeof(float));
    m.rgb = sooc_malloc((nv ? nv : 1) * 3);
    m.tri = sooc_malloc((nf ? nf : 1) * 3 * sizeof(uint32_t));
    if (!m.xyz || !m.rgb || !m.tri) {
        sooc_mesh_free(&m);
        sooc_free(buf);
        return SOOC_ENOMEM;
    }
    m.cap_vert = nv, m.cap_tri = nf;
    const unsigned char *r = d + hlen, *rend = d + n;
    for (size_t i = 0; i < nv; i++, r += vstride) {
        const int axes[3] = {ix, iy, iz}, cols[3] = {ir, ig, ib};
        for (int k = 0; k < 3; k++) {
            uint32_t u = get_u32(r + off[axes[k]]);
            memcpy(&m.xyz[3 * i + k], &u, 4);
            m.rgb[3 * i + k] = cols[k] >= 0 ? r[off[cols[k]]] : 200;
        }
    }
    size_t cs = nf ? (size_t)fp[0].list_count : 0;
    for (size_t t = 0; t < nf; t++) {
        if ((size_t)(rend - r) < cs) goto trunc;
        uint64_t k = 0;
        for (size_t q = 0; q < cs; q++) k |= (uint64_t)r[q] << (8 * q);
        r += cs;
        if (k != 3) {
            sooc_mesh_free(&m);
            sooc_free(buf);
            return sooc_seterr(SOOC_EUNSUPPORTED, "%s: face %zu has %llu vertices (triangles only)", path, t,
                               (unsigned long long)k);
        }
        if ((size_t)(rend - r) < 12) goto trunc;
        for (int q = 0; q < 3; q++, r += 4) {
            uint32_t u = get_u32(r);
            if (u >= nv) {
                sooc_mesh_free(&m);
                sooc_free(buf);
                return sooc_seterr(SOOC_EFORMAT, "%s: face %zu uses vertex %u of %zu", path, t, u, nv);
            }
            m.tri[3 * t + q] = u;
        }
    }
    sooc_free(buf);
    sooc_mesh_free(out);
    m.n_vert = nv, m.n_tri = nf;
    *out = m;
    return SOOC_OK;
trunc:
    sooc_mesh_free(&m);
    sooc_free(buf);
    return sooc_seterr(SOOC_EFORMAT, "%s: truncated face list", path);
}
