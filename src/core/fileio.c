/* CRC32, atomic saves (temp file, fsync, rename, fsync dir) and small file helpers. */
#include "sooc3d/core.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

uint32_t sooc_crc32(uint32_t crc, const void *buf, size_t n) {
    const unsigned char *p = buf;
    uLong c = crc;
    while (n > 0) {
        uInt chunk = n > (1u << 30) ? (1u << 30) : (uInt)n;
        c = crc32(c, p, chunk);
        p += chunk;
        n -= chunk;
    }
    return (uint32_t)c;
}

void sooc_path_parent(const char *path, char *out, size_t cap) {
    if (!cap) return;
    snprintf(out, cap, "%s", path);
    size_t n = strlen(out);
    while (n > 1 && out[n - 1] == '/') out[--n] = 0;
    char *slash = strrchr(out, '/');
    if (slash == out) slash[1] = 0;
    else if (slash) *slash = 0;
    else snprintf(out, cap, ".");
}

static void fsync_parent_dir(const char *path) {
    char dir[4096];
    sooc_path_parent(path, dir, sizeof dir);
    int fd = open(dir, O_RDONLY | O_DIRECTORY);
    if (fd >= 0) { fsync(fd); close(fd); }
}

sooc_status sooc_afile_open(sooc_afile *f, const char *path) {
    memset(f, 0, sizeof *f);
    size_t n = strlen(path) + 32;
    f->path = sooc_strdup(path);
    f->tmp = sooc_malloc(n);
    if (!f->path || !f->tmp) { sooc_afile_abort(f); return SOOC_ENOMEM; }
    snprintf(f->tmp, n, "%s.tmp.%ld", path, (long)getpid());
    f->fp = fopen(f->tmp, "wb");
    if (!f->fp) {
        int e = errno;
        char dir[4096];
        sooc_path_parent(path, dir, sizeof dir);
        struct stat sb;
        sooc_status s = e == ENOENT && stat(dir, &sb) != 0
                            ? sooc_seterr(SOOC_ENOTFOUND, "%s: the folder %s does not exist", path, dir)
                            : sooc_seterr(SOOC_EIO, "%s: cannot create temp file: %s", f->tmp, strerror(e));
        sooc_afile_abort(f);
        return s;
    }
    return SOOC_OK;
}

sooc_status sooc_afile_write(sooc_afile *f, const void *data, size_t n) {
    if (f->failed) return SOOC_EIO;
    if (n && fwrite(data, 1, n, (FILE *)f->fp) != n) {
        f->failed = 1;
        return sooc_seterr(SOOC_EIO, "%s: write failed: %s", f->tmp, strerror(errno));
    }
    f->crc = sooc_crc32(f->crc, data, n);
    f->nbytes += n;
    return SOOC_OK;
}

sooc_status sooc_afile_commit(sooc_afile *f) {
    FILE *fp = f->fp;
    sooc_status s = SOOC_OK;
    if (f->failed) s = SOOC_EIO;
    else if (fflush(fp) != 0 || fsync(fileno(fp)) != 0)
        s = sooc_seterr(SOOC_EIO, "%s: flush failed: %s", f->tmp, strerror(errno));
    if (fclose(fp) != 0 && s == SOOC_OK)
        s = sooc_seterr(SOOC_EIO, "%s: close failed: %s", f->tmp, strerror(errno));
    f->fp = NULL;
    if (s == SOOC_OK && rename(f->tmp, f->path) != 0)
        s = sooc_seterr(SOOC_EIO, "%s: rename to %s failed: %s", f->tmp, f->path, strerror(errno));
    if (s == SOOC_OK) fsync_parent_dir(f->path);
    else unlink(f->tmp);
    sooc_free(f->path);
    sooc_free(f->tmp);
    f->path = f->tmp = NULL;
    return s;
}

void sooc_afile_abort(sooc_afile *f) {
    if (f->fp) { fclose((FILE *)f->fp); f->fp = NULL; }
    if (f->tmp) unlink(f->tmp);
    sooc_free(f->path);
    sooc_free(f->tmp);
    f->path = f->tmp = NULL;
}

sooc_status sooc_file_write_atomic(const char *path, const void *data, size_t n) {
    sooc_afile f;
    sooc_status s = sooc_afile_open(&f, path);
    if (s) return s;
    s = sooc_afile_write(&f, data, n);
    if (s) { sooc_afile_abort(&f); return s; }
    return sooc_afile_commit(&f);
}

sooc_status sooc_file_read_all(const char *path, size_t max_bytes, void **out, size_t *n) {
    *out = NULL;
    if (n) *n = 0;
    FILE *fp = fopen(path, "rb");
    if (!fp)
        return sooc_seterr(errno == ENOENT ? SOOC_ENOTFOUND : SOOC_EIO, "%s: cannot open: %s", path,
                           strerror(errno));
    struct stat st;
    if (fstat(fileno(fp), &st) != 0 || !S_ISREG(st.st_mode)) {
        fclose(fp);
        return sooc_seterr(SOOC_EIO, "%s: not a regular file", path);
    }
    if ((uint64_t)st.st_size > max_bytes) {
        fclose(fp);
        return sooc_seterr(SOOC_EFORMAT, "%s: file is %lld bytes, more than the %zu allowed", path,
                           (long long)st.st_size, max_bytes);
    }
    size_t sz = (size_t)st.st_size;
    char *buf = sooc_malloc(sz + 1);
    if (!buf) { fclose(fp); return SOOC_ENOMEM; }
    if (sz && fread(buf, 1, sz, fp) != sz) {
        fclose(fp);
        sooc_free(buf);
        return sooc_seterr(SOOC_EIO, "%s: read failed", path);
    }
    fclose(fp);
    buf[sz] = 0;
    *out = buf;
    if (n) *n = sz;
    return SOOC_OK;
}

int sooc_file_exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISREG(st.st_mode);
}

int sooc_dir_exists(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISDIR(st.st_mode);
}

sooc_status sooc_mkdirs(const char *path) {
    char buf[4096];
    size_t n = strlen(path);
    if (n == 0 || n >= sizeof buf) return sooc_seterr(SOOC_EINVAL, "mkdir: bad path '%s'", path);
    memcpy(buf, path, n + 1);
    for (size_t i = 1; i <= n; i++) {
        if (buf[i] == '/' || buf[i] == 0) {
            char c = buf[i];
            buf[i] = 0;
            if (mkdir(buf, 0755) != 0 && errno != EEXIST)
                return sooc_seterr(SOOC_EIO, "%s: cannot create directory: %s", buf, strerror(errno));
            buf[i] = c;
        }
    }
    if (!sooc_dir_exists(path)) return sooc_seterr(SOOC_EIO, "%s: exists and is not a directory", path);
    return SOOC_OK;
}

sooc_status sooc_path_join(char *out, size_t cap, const char *a, const char *b) {
    size_t la = strlen(a);
    int n = (la && a[la - 1] == '/') ? snprintf(out, cap, "%s%s", a, b) : snprintf(out, cap, "%s/%s", a, b);
    if (n < 0 || (size_t)n >= cap) return sooc_seterr(SOOC_EINVAL, "path too long: %s/%s", a, b);
    return SOOC_OK;
}

sooc_status sooc_file_id(const char *path, char *id, size_t cap, uint64_t *hash) {
    if (!path || !id || cap < 48) return sooc_seterr(SOOC_EINVAL, "file id: bad arguments");
    void *buf = NULL;
    size_t nb = 0;
    sooc_status st = sooc_file_read_all(path, (size_t)1 << 31, &buf, &nb);
    if (st) return st;
    uint64_t h = 0xcbf29ce484222325ull;
    for (size_t i = 0; i < nb; i++) h = (h ^ ((const unsigned char *)buf)[i]) * 0x100000001b3ull;
    sooc_free(buf);
    snprintf(id, cap, "fnv1a64:%016llx bytes:%zu", (unsigned long long)h, nb);
    if (hash) *hash = h;
    return SOOC_OK;
}

/* Write to "<path>.tmp" and rename over path: readers never see a partial
 * file. No fsync (datasets write thousands of small files; a crash may lose
 * recent files but never leaves a truncated one under the final name). */
sooc_status sooc_file_write_bulk(const char *path, const void *buf, size_t n) {
    char tmp[4200];
    if (snprintf(tmp, sizeof tmp, "%s.tmp", path) >= (int)sizeof tmp)
        return sooc_seterr(SOOC_EINVAL, "%s: path too long", path);
    FILE *fp = fopen(tmp, "wb");
    if (!fp) return sooc_seterr(SOOC_EIO, "%s: cannot create: %s", tmp, strerror(errno));
    size_t w = fwrite(buf, 1, n, fp);
    int bad = w != n || fflush(fp) != 0;
    if (fclose(fp) != 0) bad = 1;
    if (bad || rename(tmp, path) != 0) {
        int e = errno;
        remove(tmp);
        return sooc_seterr(SOOC_EIO, "%s: write failed: %s", path, strerror(e));
    }
    return SOOC_OK;
}
