/* The sizes a MATLAB v5 MAT-file declares, checked before libmatio reads it
 * (seq_ycb.c): libmatio allocates (and clears) each array at the size its
 * header declares, so a damaged header would make it allocate gigabytes. */
#include "seq_impl.h"

#include <stdint.h>
#include <string.h>
#include <zlib.h>

#define MAT_MAX_ELEMS (1ull << 27)   /* YCB-Video's largest variable, vertmap, has 921,600 */
#define MAT_MIN_MATRIX 40           /* array flags (16), dimensions (16: two), name (8: an inline tag) */

static uint32_t rd32(const uint8_t *p, int be) {
    return be ? (uint32_t)p[0] << 24 | (uint32_t)p[1] << 16 | (uint32_t)p[2] << 8 | p[3]
              : (uint32_t)p[3] << 24 | (uint32_t)p[2] << 16 | (uint32_t)p[1] << 8 | p[0];
}

/* A miMATRIX's header (array flags, dimensions, name, then the first data
 * element) in p[0..n): every element there must fit in `room` bytes, and so
 * must the array's elements (at least a byte each). */
static sooc_status check_matrix(const char *path, const uint8_t *p, size_t n, int be, uint64_t room, long off,
                                int whole) {
    uint32_t cls = 0;
    const uint8_t *dims = NULL;
    uint32_t dn = 0;
    size_t at = 0;
    int k = 0;
    for (; k < 4 && at + 8 <= n; k++) {
        uint32_t t = rd32(p + at, be), sz;
        size_t adv;
        if (t >> 16) { sz = t >> 16; t &= 0xffff; adv = 8; }
        else { sz = rd32(p + at + 4, be); adv = 8 + (size_t)sz + (sz % 8 ? 8 - sz % 8 : 0); }
        if (sz > room)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array's element %d declares %u bytes, more than the "
                               "file can hold (%llu bytes): a corrupt MAT-file", path, off, k, sz,
                               (unsigned long long)room);
        if (t > 18 && k < 3)
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array's element %d has data type %u (MAT-files use 1-18): "
                               "a corrupt MAT-file", path, off, k, t);
        /* the layout libmatio reads without looking at the tags: array flags miUINT32 of 8 bytes, dimensions
         * miINT32 of two or more, the name miINT8 */
        if ((k == 0 && (t != 6 || sz != 8 || adv != 16)) || (k == 1 && (t != 5 || sz < 8 || sz % 4 || adv == 8)) ||
            (k == 2 && t != 1))
            return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array's %s element has data type %u and %u bytes: a "
                               "corrupt MAT-file", path, off, k == 0 ? "flags" : k == 1 ? "dimensions" : "name", t, sz);
        if (k == 0 && t == 6 && sz >= 8 && at + 12 <= n) cls = rd32(p + at + 8, be) & 0xff;
        if (k == 1 && t == 5 && !(rd32(p + at, be) >> 16)) { dims = p + at + 8; dn = sz; }
        at += adv;
    }
    /* p[0..n) is the whole array (whole): its flags, dimensions, name and data lie in it (libmatio reads
     * them from the elements after it otherwise, or allocates the size a missing data tag declares) */
    if (whole && (k < 4 || at > n))
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array's flags, dimensions, name and data run past its %zu "
                           "bytes: a corrupt MAT-file", path, off, n);
    /* character, sparse and numeric arrays (classes 4-15) only: cells, structs, objects, function handles and
     * opaque classes nest arrays, and libmatio leaks what it has read of a damaged one; a YCB-Video meta.mat
     * holds numeric arrays only */
    if (cls < 4 || cls > 15)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array of MATLAB class %u (%s): sooc3d reads numeric "
                           "arrays from a meta.mat, as YCB-Video's hold", path, off, cls,
                           cls == 1 ? "cell" : cls == 2 ? "struct" : cls == 3 ? "object" : cls == 16 ? "function" :
                           cls == 17 ? "opaque" : "unknown");
    if (!dims || dn % 4 || dn > 4 * 32 || (size_t)(dims - p) + dn > n) return SOOC_OK;
    if (cls == 5) return SOOC_OK;   /* sparse */
    uint64_t prod = 1;
    for (uint32_t k = 0; k < dn / 4; k++) {
        uint32_t v = rd32(dims + 4 * k, be);
        if (v > 0x7fffffffu) prod = UINT64_MAX;
        else if (prod != UINT64_MAX) prod = v && prod > UINT64_MAX / v ? UINT64_MAX : prod * v;
    }
    if (prod == UINT64_MAX)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array declares a dimension of 2^31 or more: a corrupt "
                           "MAT-file", path, off);
    if (prod > room || prod > MAT_MAX_ELEMS)
        return sooc_seterr(SOOC_EFORMAT, "%s: offset %ld: an array declares %llu elements, more than the file can hold "
                           "(%llu bytes): a corrupt MAT-file", path, off, (unsigned long long)prod,
                           (unsigned long long)room);
    return SOOC_OK;
}

sooc_status sooc_seqi_mat_check_sizes(const char *path, const uint8_t *f, size_t size) {
    if (size < 128) return SOOC_OK;
    int be = f[126] == 'M' && f[127] == 'I';
    size_t off = 128;
    while (off + 8 <= size) {
        uint32_t type = rd32(f + off, be), nb;
        if (type >> 16) { off += 8; continue; }      /* a small element: 4 bytes of data inline */
        nb = rd32(f + off + 4, be);
        if (nb > size - off - 8)
            return sooc_seterr(SOOC_EFORMAT, "%s: truncated or corrupt MAT-file: offset %zu: an element of %u bytes runs "
                               "past the end of the file (%zu bytes)", path, off, nb, size);
        const uint8_t *d = f + off + 8;
        sooc_status st = SOOC_OK;
        /* an array's header (flags, dimensions, name tags) takes MAT_MIN_MATRIX bytes: libmatio reads that
         * much whatever the element declares, so a shorter one would be read from the elements after it */
        if (type == 14 && nb < MAT_MIN_MATRIX)
            return sooc_seterr(SOOC_EFORMAT, "%s: corrupt MAT-file: offset %zu: an array element of %u bytes, too "
                               "small for an array's header (%d bytes)", path, off, nb, MAT_MIN_MATRIX);
        if (type == 14) st = check_matrix(path, d, nb, be, nb, (long)off, 1);
        if (type == 15) {                            /* miCOMPRESSED: the inner header, inflated */
            uint8_t hdr[8 + 16 + 8 + 4 * 32 + 8 + 256];   /* tag, flags, dims (32), name (256 characters) */
            z_stream z;
            memset(&z, 0, sizeof z);
            if (inflateInit(&z) == Z_OK) {
                z.next_in = (Bytef *)d;
                z.avail_in = nb;
                z.next_out = hdr;
                z.avail_out = sizeof hdr;
                int r = inflate(&z, Z_SYNC_FLUSH);
                size_t got = sizeof hdr - z.avail_out;
                inflateEnd(&z);
                if ((r == Z_OK || r == Z_STREAM_END || r == Z_BUF_ERROR) && got >= 8 && rd32(hdr, be) == 14) {
                    uint64_t inner = rd32(hdr + 4, be), room = (uint64_t)nb * 1032 + 1024;
                    if (inner < MAT_MIN_MATRIX)
                        return sooc_seterr(SOOC_EFORMAT, "%s: corrupt MAT-file: offset %zu: a compressed array of %llu "
                                           "bytes, too small for an array's header (%d bytes)", path, off,
                                           (unsigned long long)inner, MAT_MIN_MATRIX);
                    /* whole: the stream inflated to its end (the buffer not filled) or past the array */
                    st = check_matrix(path, hdr + 8, got - 8, be, inner < room ? inner : room, (long)off,
                                      got < sizeof hdr || got - 8 >= inner);
                }
            }
        }
        if (st) return st;
        off += 8 + nb;
        if (type != 15) off += (8 - nb % 8) % 8;
    }
    return SOOC_OK;
}
