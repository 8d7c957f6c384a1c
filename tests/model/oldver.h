/* Older model checkpoints for the load tests: a copy of a saved model file
 * with its config cut to an older version's size, as that version wrote it
 * (docs/model.md "Checkpoint"). Header-only. */
#ifndef SOOC3D_TEST_OLDVER_H
#define SOOC3D_TEST_OLDVER_H

#include <stdio.h>
#include <string.h>

#include "sooc3d/core.h"

/* Write dst: src's bytes with version `ver`, the config cut to `csz_old`
 * bytes (the fields appended since dropped), the CRC recomputed. `ver_hdr`
 * is the version written in the header (normally ver; another value makes a
 * file whose header and config size disagree). 0 on success. */
static inline int tm_write_old_version(const char *src, const char *dst, uint32_t ver_hdr, uint32_t csz_old) {
    void *buf = NULL;
    size_t n = 0;
    if (sooc_file_read_all(src, (size_t)1 << 30, &buf, &n)) return -1;
    const uint8_t *b = buf;
    uint32_t csz;
    memcpy(&csz, b + 12, 4);
    if (csz_old > csz || n < 16 + (size_t)csz + 4) {
        sooc_free(buf);
        return -1;
    }
    size_t no = n - (csz - csz_old);
    uint8_t *o = sooc_malloc(no);
    if (!o) {
        sooc_free(buf);
        return -1;
    }
    memcpy(o, b, 16 + csz_old);
    memcpy(o + 8, &ver_hdr, 4);
    memcpy(o + 12, &csz_old, 4);
    memcpy(o + 16 + csz_old, b + 16 + csz, n - 16 - csz);
    uint32_t crc = sooc_crc32(0, o, no - 4);
    memcpy(o + no - 4, &crc, 4);
    FILE *fp = fopen(dst, "wb");
    int rc = fp && fwrite(o, 1, no, fp) == no ? 0 : -1;
    if (fp && fclose(fp)) rc = -1;
    sooc_free(o);
    sooc_free(buf);
    return rc;
}

#endif
