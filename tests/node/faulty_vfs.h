/* A shim SQLite VFS for tests: it wraps the default VFS and makes chosen
 * writes fail, deterministically. Every xWrite (on the database, its WAL or a
 * journal) is numbered from 1 (fvfs_writes() counts them); the writes
 * numbered [from, to) return `code` (SQLITE_FULL, SQLITE_IOERR_WRITE, ...)
 * without writing. fvfs_install() registers it as the default VFS of the
 * process, so every connection opened afterwards goes through it. */
#ifndef SOOC3D_TEST_FAULTY_VFS_H
#define SOOC3D_TEST_FAULTY_VFS_H

#include <sqlite3.h>
#include <stdatomic.h>
#include <stdint.h>
#include <string.h>

typedef struct fvfs_file {
    sqlite3_file base;
    sqlite3_file *real;   /* follows this struct in the same allocation */
} fvfs_file;

static sqlite3_vfs *g_fvfs_real;
static sqlite3_vfs g_fvfs;
static sqlite3_io_methods g_fvfs_io;
static atomic_llong g_fvfs_n, g_fvfs_from = INT64_MAX, g_fvfs_to = INT64_MAX, g_fvfs_failed;
static atomic_int g_fvfs_code = SQLITE_FULL;

/* Writes numbered [from, to) fail with code (to = INT64_MAX: all from `from` on). */
static inline void fvfs_fail(int64_t from, int64_t to, int code) {
    atomic_store(&g_fvfs_code, code);
    atomic_store(&g_fvfs_to, to);
    atomic_store(&g_fvfs_from, from);
}
static inline void fvfs_off(void) { fvfs_fail(INT64_MAX, INT64_MAX, SQLITE_FULL); }
static inline int64_t fvfs_writes(void) { return atomic_load(&g_fvfs_n); }
static inline int64_t fvfs_failed(void) { return atomic_load(&g_fvfs_failed); }
static inline void fvfs_reset_count(void) {
    atomic_store(&g_fvfs_n, 0);
    atomic_store(&g_fvfs_failed, 0);
}

#define FVFS_REAL(f) (((fvfs_file *)(f))->real)
static int fvfs_close(sqlite3_file *f) {
    int rc = FVFS_REAL(f)->pMethods ? FVFS_REAL(f)->pMethods->xClose(FVFS_REAL(f)) : SQLITE_OK;
    return rc;
}
static int fvfs_read(sqlite3_file *f, void *b, int n, sqlite3_int64 o) {
    return FVFS_REAL(f)->pMethods->xRead(FVFS_REAL(f), b, n, o);
}
static int fvfs_write(sqlite3_file *f, const void *b, int n, sqlite3_int64 o) {
    long long k = atomic_fetch_add(&g_fvfs_n, 1) + 1;
    if (k >= atomic_load(&g_fvfs_from) && k < atomic_load(&g_fvfs_to)) {
        atomic_fetch_add(&g_fvfs_failed, 1);
        return atomic_load(&g_fvfs_code);
    }
    return FVFS_REAL(f)->pMethods->xWrite(FVFS_REAL(f), b, n, o);
}
static int fvfs_truncate(sqlite3_file *f, sqlite3_int64 s) { return FVFS_REAL(f)->pMethods->xTruncate(FVFS_REAL(f), s); }
static int fvfs_sync(sqlite3_file *f, int fl) { return FVFS_REAL(f)->pMethods->xSync(FVFS_REAL(f), fl); }
static int fvfs_size(sqlite3_file *f, sqlite3_int64 *s) { return FVFS_REAL(f)->pMethods->xFileSize(FVFS_REAL(f), s); }
static int fvfs_lock(sqlite3_file *f, int l) { return FVFS_REAL(f)->pMethods->xLock(FVFS_REAL(f), l); }
static int fvfs_unlock(sqlite3_file *f, int l) { return FVFS_REAL(f)->pMethods->xUnlock(FVFS_REAL(f), l); }
static int fvfs_check(sqlite3_file *f, int *r) { return FVFS_REAL(f)->pMethods->xCheckReservedLock(FVFS_REAL(f), r); }
static int fvfs_fctl(sqlite3_file *f, int op, void *a) { return FVFS_REAL(f)->pMethods->xFileControl(FVFS_REAL(f), op, a); }
static int fvfs_sector(sqlite3_file *f) { return FVFS_REAL(f)->pMethods->xSectorSize(FVFS_REAL(f)); }
static int fvfs_dev(sqlite3_file *f) { return FVFS_REAL(f)->pMethods->xDeviceCharacteristics(FVFS_REAL(f)); }
static int fvfs_shmmap(sqlite3_file *f, int pg, int sz, int ext, void volatile **pp) {
    return FVFS_REAL(f)->pMethods->xShmMap(FVFS_REAL(f), pg, sz, ext, pp);
}
static int fvfs_shmlock(sqlite3_file *f, int o, int n, int fl) { return FVFS_REAL(f)->pMethods->xShmLock(FVFS_REAL(f), o, n, fl); }
static void fvfs_shmbarrier(sqlite3_file *f) { FVFS_REAL(f)->pMethods->xShmBarrier(FVFS_REAL(f)); }
static int fvfs_shmunmap(sqlite3_file *f, int del) { return FVFS_REAL(f)->pMethods->xShmUnmap(FVFS_REAL(f), del); }
static int fvfs_fetch(sqlite3_file *f, sqlite3_int64 o, int n, void **pp) {
    return FVFS_REAL(f)->pMethods->xFetch(FVFS_REAL(f), o, n, pp);
}
static int fvfs_unfetch(sqlite3_file *f, sqlite3_int64 o, void *p) { return FVFS_REAL(f)->pMethods->xUnfetch(FVFS_REAL(f), o, p); }

static int fvfs_open(sqlite3_vfs *v, const char *name, sqlite3_file *f, int flags, int *out) {
    (void)v;
    fvfs_file *w = (fvfs_file *)f;
    w->real = (sqlite3_file *)(w + 1);
    memset(w->real, 0, (size_t)g_fvfs_real->szOsFile);
    int rc = g_fvfs_real->xOpen(g_fvfs_real, name, w->real, flags, out);
    w->base.pMethods = w->real->pMethods ? &g_fvfs_io : NULL;
    return rc;
}
static int fvfs_delete(sqlite3_vfs *v, const char *n, int s) { (void)v; return g_fvfs_real->xDelete(g_fvfs_real, n, s); }
static int fvfs_access(sqlite3_vfs *v, const char *n, int fl, int *r) { (void)v; return g_fvfs_real->xAccess(g_fvfs_real, n, fl, r); }
static int fvfs_full(sqlite3_vfs *v, const char *n, int k, char *o) { (void)v; return g_fvfs_real->xFullPathname(g_fvfs_real, n, k, o); }
static int fvfs_rand(sqlite3_vfs *v, int n, char *o) { (void)v; return g_fvfs_real->xRandomness(g_fvfs_real, n, o); }
static int fvfs_sleep(sqlite3_vfs *v, int us) { (void)v; return g_fvfs_real->xSleep(g_fvfs_real, us); }
static int fvfs_time(sqlite3_vfs *v, double *t) { (void)v; return g_fvfs_real->xCurrentTime(g_fvfs_real, t); }
static int fvfs_lasterr(sqlite3_vfs *v, int n, char *b) { (void)v; return g_fvfs_real->xGetLastError(g_fvfs_real, n, b); }
static int fvfs_time64(sqlite3_vfs *v, sqlite3_int64 *t) { (void)v; return g_fvfs_real->xCurrentTimeInt64(g_fvfs_real, t); }

/* Register the shim as the default VFS (once). 0 on success. */
static inline int fvfs_install(void) {
    if (g_fvfs_real) return 0;
    sqlite3_initialize();
    g_fvfs_real = sqlite3_vfs_find(NULL);
    if (!g_fvfs_real || g_fvfs_real->iVersion < 2) return -1;
    const sqlite3_io_methods io = {3, fvfs_close, fvfs_read, fvfs_write, fvfs_truncate, fvfs_sync, fvfs_size,
                                   fvfs_lock, fvfs_unlock, fvfs_check, fvfs_fctl, fvfs_sector, fvfs_dev,
                                   fvfs_shmmap, fvfs_shmlock, fvfs_shmbarrier, fvfs_shmunmap, fvfs_fetch,
                                   fvfs_unfetch};
    g_fvfs_io = io;
    memset(&g_fvfs, 0, sizeof g_fvfs);
    g_fvfs.iVersion = 2;
    g_fvfs.szOsFile = (int)sizeof(fvfs_file) + g_fvfs_real->szOsFile;
    g_fvfs.mxPathname = g_fvfs_real->mxPathname;
    g_fvfs.zName = "sooc3d-faulty";
    g_fvfs.xOpen = fvfs_open;
    g_fvfs.xDelete = fvfs_delete;
    g_fvfs.xAccess = fvfs_access;
    g_fvfs.xFullPathname = fvfs_full;
    g_fvfs.xRandomness = fvfs_rand;
    g_fvfs.xSleep = fvfs_sleep;
    g_fvfs.xCurrentTime = fvfs_time;
    g_fvfs.xGetLastError = fvfs_lasterr;
    g_fvfs.xCurrentTimeInt64 = fvfs_time64;
    return sqlite3_vfs_register(&g_fvfs, 1) == SQLITE_OK ? 0 : -1;
}

#endif
