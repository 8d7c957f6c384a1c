/*
 * sooc3d core: status codes and messages, the log callback, the counted
 * allocator, a deterministic RNG, clocks, a terminal progress line, CRC32 and
 * atomic file saving.
 *
 * Conventions used by every module:
 *  - Fallible functions return sooc_status (0 = OK, negative = error). When
 *    they fail they also leave a message, readable with sooc_errmsg() on the
 *    same thread until the next failure. Messages name the file/key/line
 *    involved, e.g. "calib/x.yaml:12: camera_matrix: expected 9 numbers".
 *  - The library never prints and never exits. Text goes through the log
 *    callback (default: none; the CLI installs one that writes to stderr).
 *  - Heap memory comes from sooc_malloc/sooc_calloc/sooc_free: 64-byte aligned,
 *    counted, and with fault injection for tests.
 */
#ifndef SOOC3D_CORE_H
#define SOOC3D_CORE_H

#include <stddef.h>
#include <stdint.h>
#include <stdarg.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---------------------------------------------------------------- status */

typedef enum sooc_status {
    SOOC_OK = 0,
    SOOC_ERR = -1,         /* generic failure                                */
    SOOC_ENOMEM = -2,      /* allocation failed                              */
    SOOC_EINVAL = -3,      /* bad argument or bad value in an input file     */
    SOOC_EIO = -4,         /* read/write/open failed                         */
    SOOC_EFORMAT = -5,     /* file is malformed, truncated or corrupt        */
    SOOC_EVERSION = -6,    /* file has a version/config we cannot read       */
    SOOC_ENOTFOUND = -7,   /* missing file, device, key or entry             */
    SOOC_EUNSUPPORTED = -8,/* feature not built in or not supported by device */
    SOOC_ETIMEOUT = -9,    /* timed out                                      */
    SOOC_EBUSY = -10,      /* resource busy (e.g. seqlock retries exhausted) */
    SOOC_EEOF = -11,       /* end of stream                                  */
    SOOC_ENUMERIC = -12,   /* non-finite value where a finite one is needed  */
    SOOC_EINTERRUPTED = -13/* stopped by a signal / stop request            */
} sooc_status;

/* Name of a status code, e.g. "EFORMAT". Never NULL. */
const char *sooc_status_str(sooc_status s);

/* Record an error message for the calling thread and return `s` (so callers
 * can write `return sooc_seterr(SOOC_EINVAL, "%s:%d: ...", path, line);`). */
sooc_status sooc_seterr(sooc_status s, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Prefix the current message with "<prefix>: " (adds context while unwinding). */
sooc_status sooc_adderr(sooc_status s, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* The calling thread's last error message ("" if none). Thread-local storage. */
const char *sooc_errmsg(void);
void sooc_clearerr(void);

/* Always-on assertion for contract violations (programming errors, not input
 * errors). Calls the log callback at FATAL and then abort(). */
_Noreturn void sooc_assert_fail(const char *expr, const char *file, int line);
#define SOOC_ASSERT(x) ((x) ? (void)0 : sooc_assert_fail(#x, __FILE__, __LINE__))

/* ------------------------------------------------------------------- log */

typedef enum sooc_log_level {
    SOOC_LOG_DEBUG = 0, SOOC_LOG_INFO = 1, SOOC_LOG_WARN = 2,
    SOOC_LOG_ERROR = 3, SOOC_LOG_FATAL = 4
} sooc_log_level;

typedef void (*sooc_log_fn)(void *user, sooc_log_level level, const char *msg);

/* Install the log sink (NULL = drop everything). Thread-safe to call log;
 * set the callback before starting threads. */
void sooc_log_set_callback(sooc_log_fn fn, void *user);
void sooc_log_set_level(sooc_log_level min_level);
sooc_log_level sooc_log_get_level(void);
void sooc_log(sooc_log_level level, const char *fmt, ...)
    __attribute__((format(printf, 2, 3)));
/* Parse "debug|info|warn|error"; returns SOOC_EINVAL on anything else. */
sooc_status sooc_log_level_parse(const char *s, sooc_log_level *out);

/* ------------------------------------------------------------- allocator */

/* 64-byte aligned allocation. Returns NULL on failure (and sets the error
 * message). sooc_free(NULL) is a no-op. */
void *sooc_malloc(size_t n);
void *sooc_calloc(size_t count, size_t size);   /* overflow-checked, zeroed */
void *sooc_realloc(void *p, size_t n);           /* keeps 64-byte alignment */
void sooc_free(void *p);
char *sooc_strdup(const char *s);

typedef struct sooc_alloc_stats {
    uint64_t live_bytes, peak_bytes, n_alloc, n_free;
} sooc_alloc_stats;
void sooc_alloc_get_stats(sooc_alloc_stats *out);
/* Test hook: after `n_ok` more successful allocations, the next `n_fail`
 * allocations fail. (0, 0) disables injection. */
void sooc_alloc_fault_inject(uint64_t n_ok, uint64_t n_fail);

/* ------------------------------------------------------------------- RNG */

/* xoshiro256** seeded through splitmix64 from (seed, stream). Distinct streams
 * are independent, so work item i can own stream i: results then do not
 * depend on the thread count. Pure value type; copy it freely. */
typedef struct sooc_rng { uint64_t s[4]; } sooc_rng;

void sooc_rng_seed(sooc_rng *r, uint64_t seed, uint64_t stream);
uint64_t sooc_rng_u64(sooc_rng *r);
uint32_t sooc_rng_u32(sooc_rng *r);
double sooc_rng_uniform(sooc_rng *r);                  /* [0, 1), 53 bits   */
float sooc_rng_uniformf(sooc_rng *r);                  /* [0, 1), 24 bits   */
double sooc_rng_uniform_open(sooc_rng *r);             /* (0, 1)            */
double sooc_rng_range(sooc_rng *r, double lo, double hi);
uint32_t sooc_rng_below(sooc_rng *r, uint32_t n);      /* [0, n), unbiased  */
double sooc_rng_normal(sooc_rng *r);                   /* N(0,1), Box-Muller, no cached state */
double sooc_rng_logistic(sooc_rng *r);                 /* log U - log(1-U)  */

/* ----------------------------------------------------------------- clock */

int64_t sooc_now_ns(void);        /* CLOCK_MONOTONIC */
int64_t sooc_realtime_ns(void);   /* CLOCK_REALTIME  */
double sooc_seconds(void);        /* CLOCK_MONOTONIC in seconds */

/* -------------------------------------------------------------- progress */

/* A one-line progress display: "label  123/456  27% 12.3 it/s ETA 0:42  extra".
 * Redrawn in place when stderr is a terminal (at most 10 Hz), otherwise a full
 * line every `log_every_s` seconds. Output goes to stderr: this is for CLI
 * programs, not the library. */
typedef struct sooc_progress {
    const char *label;
    uint64_t total, done;
    double t0, t_last;
    double log_every_s;
    int tty;
    int last_len;
} sooc_progress;

void sooc_progress_begin(sooc_progress *p, const char *label, uint64_t total);
/* Set `done` and redraw; `extra` (may be NULL) is appended, e.g. losses. */
void sooc_progress_update(sooc_progress *p, uint64_t done, const char *extra);
void sooc_progress_end(sooc_progress *p, const char *extra);

/* ------------------------------------------------------------------ files */

/* zlib CRC-32 of a buffer; `crc` is the running value (start from 0). */
uint32_t sooc_crc32(uint32_t crc, const void *buf, size_t n);

/* Atomic save: write to "<path>.tmp.<pid>", fsync, rename over `path`, fsync
 * the directory. On any failure the old file is left untouched. */
sooc_status sooc_file_write_atomic(const char *path, const void *data, size_t n);
/* Write `data` to "<path>.tmp" and rename it over `path`, without fsync: bulk
 * dataset files (frames, meshes, pictures) that a crash may lose whole but
 * never leaves half-written. */
sooc_status sooc_file_write_bulk(const char *path, const void *data, size_t n);

/* Streaming variant: open a temp file next to `path`, write with
 * sooc_afile_write, then sooc_afile_commit (fsync + rename) or
 * sooc_afile_abort (unlink). A CRC32 of everything written is kept. */
typedef struct sooc_afile {
    void *fp;          /* FILE* */
    char *path, *tmp;
    uint32_t crc;
    uint64_t nbytes;
    int failed;
} sooc_afile;
sooc_status sooc_afile_open(sooc_afile *f, const char *path);
sooc_status sooc_afile_write(sooc_afile *f, const void *data, size_t n);
sooc_status sooc_afile_commit(sooc_afile *f);
void sooc_afile_abort(sooc_afile *f);

/* ------------------------------------------------------- string builder */

/* A growable text buffer (sooc_malloc'd, NUL-terminated): printf appends;
 * after an allocation or format failure `oom` is set and later appends do
 * nothing, so a caller checks once at the end. The caller owns p (sooc_free). */
typedef struct sooc_strbuf {
    char *p;
    size_t n, cap;
    int oom;
} sooc_strbuf;
void sooc_strbuf_printf(sooc_strbuf *b, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

/* Read a whole file into a sooc_malloc'd buffer (NUL-terminated for text use).
 * Refuses files larger than max_bytes with SOOC_EFORMAT. */
sooc_status sooc_file_read_all(const char *path, size_t max_bytes, void **out, size_t *n);
/* A file's content identity, as a map database stores its model's
 * (mapstore model_id): "fnv1a64:<16 hex> bytes:<n>", the 64-bit FNV-1a of
 * every byte (of a checkpoint too: a CRC32 of a file that ends with its own
 * CRC32 is a constant). cap >= 48; *hash may be NULL. Files up to 2 GiB. */
sooc_status sooc_file_id(const char *path, char *id, size_t cap, uint64_t *hash);
int sooc_file_exists(const char *path);
int sooc_dir_exists(const char *path);
/* mkdir -p */
sooc_status sooc_mkdirs(const char *path);
/* Join path parts into `out` (cap bytes). Fails with SOOC_EINVAL if too long. */
sooc_status sooc_path_join(char *out, size_t cap, const char *a, const char *b);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_CORE_H */
