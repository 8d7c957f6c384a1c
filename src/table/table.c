/*
 * sooc3d shared-memory object table: reader and writer (see include/sooc3d/table.h
 * for the API and docs/shm.md for the protocol).
 *
 * This file depends on nothing else from sooc3d, so it can be built as the
 * standalone shared library libsooc3d_table.so that planners link against.
 * Like the rest of the library it never prints and never exits.
 *
 * Memory-model notes (H.-J. Boehm, "Can seqlocks get along with programming
 * language memory models?", MSPC 2012):
 *   writer: seq = s+1 (relaxed); fence(release); payload (relaxed stores); seq = s+2 (release)
 *   reader: s0 = seq (acquire), odd -> retry; payload (relaxed loads);
 *           fence(acquire); s1 = seq (relaxed); accept iff s0 == s1.
 * Payload words are accessed as _Atomic uint64_t through casts of the shm
 * pointers; the header asserts that _Atomic uint64_t is a plain 8-byte word.
 */
#include "sooc3d/table.h"

#include <errno.h>
#include <fcntl.h>
#include <pthread.h>
#include <sched.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <sys/mman.h>
#include <sys/random.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#define WORDS_PER_RECORD (SOOC_TABLE_RECORD_SIZE / 8u)
#define META_OFF 256u                          /* start of the header batch block */
#define META_WORDS ((408u - META_OFF) / 8u)    /* latent_dim .. T_src_map         */
#define REUSE_EPOCHS 2u /* a REMOVED slot is reused in batches >= removal epoch + 2 */
#define SNAPSHOT_SLEEP_NS 200000L /* pause between snapshot retries while table_seq is odd */

typedef _Atomic(uint64_t) aword;

/* ------------------------------------------------------------ utilities */

const char *sooc_table_strerror(int code) {
    switch (code) {
    case SOOC_TABLE_OK: return "ok";
    case SOOC_TABLE_EINVAL: return "invalid argument or table name";
    case SOOC_TABLE_ENOENT: return "no such table or object";
    case SOOC_TABLE_EVERSION: return "incompatible table (ABI, sizes or schema hash)";
    case SOOC_TABLE_ENOTREADY: return "table header not published yet (retry)";
    case SOOC_TABLE_EBUSY: return "table busy (seqlock retries exhausted)";
    case SOOC_TABLE_ELOCKED: return "another writer owns the table";
    case SOOC_TABLE_EFULL: return "table full (no free slot)";
    case SOOC_TABLE_ERANGE: return "output buffer too small";
    case SOOC_TABLE_ESTATE: return "call out of order (batch state)";
    case SOOC_TABLE_ENOMEM: return "out of memory";
    case SOOC_TABLE_ESYS: return "system call failed (see errno)";
    default: return "unknown table error";
    }
}

uint64_t sooc_table_schema_hash(void) {
    static const char s[] = SOOC_TABLE_SCHEMA_STRING;
    uint64_t h = 0xcbf29ce484222325ull; /* FNV-1a 64 offset basis */
    for (const unsigned char *p = (const unsigned char *)s; *p; p++) {
        h ^= *p;
        h *= 0x100000001b3ull; /* FNV prime */
    }
    return h;
}

int sooc_table_validate_name(const char *name) {
    if (!name || !name[0] || name[0] == '.') return SOOC_TABLE_EINVAL;
    size_t n = 0;
    for (const char *p = name; *p; p++, n++) {
        char c = *p;
        int ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                 c == '_' || c == '.' || c == '-';
        if (!ok || n >= SOOC_TABLE_NAME_MAX) return SOOC_TABLE_EINVAL;
    }
    return SOOC_TABLE_OK;
}

int sooc_table_shm_name(const char *name, char *out, unsigned cap) {
    if (!out || sooc_table_validate_name(name) != 0) return SOOC_TABLE_EINVAL;
    size_t need = strlen(SOOC_TABLE_SHM_PREFIX) + strlen(name) + 1;
    if (need > cap) return SOOC_TABLE_ERANGE;
    memcpy(out, SOOC_TABLE_SHM_PREFIX, strlen(SOOC_TABLE_SHM_PREFIX));
    memcpy(out + strlen(SOOC_TABLE_SHM_PREFIX), name, strlen(name) + 1);
    return SOOC_TABLE_OK;
}

static int64_t mono_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static int64_t real_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static void sleep_ns(long ns) {
    struct timespec ts = {0, ns};
    while (nanosleep(&ts, &ts) != 0 && errno == EINTR) {
    }
}

static inline void cpu_relax(void) {
#if defined(__x86_64__) || defined(__i386__)
    __builtin_ia32_pause();
#endif
}

/* Relaxed 64-bit copies between shm and private memory. */
static inline void load_words(uint64_t *dst, const void *src, unsigned n) {
    const aword *s = (const aword *)src;
    for (unsigned i = 0; i < n; i++) dst[i] = atomic_load_explicit(&s[i], memory_order_relaxed);
}
static inline void store_words(void *dst, const uint64_t *src, unsigned n) {
    aword *d = (aword *)dst;
    for (unsigned i = 0; i < n; i++) atomic_store_explicit(&d[i], src[i], memory_order_relaxed);
}

/* Header checks shared by readers and a restarting writer. */
static int check_header(const sooc_table_header *h, size_t size) {
    if (atomic_load_explicit(&h->magic, memory_order_acquire) != SOOC_TABLE_MAGIC)
        return SOOC_TABLE_ENOTREADY;
    if (h->abi_major != SOOC_TABLE_ABI_MAJOR || h->header_size != SOOC_TABLE_HEADER_SIZE ||
        h->record_size != SOOC_TABLE_RECORD_SIZE || h->schema_hash != SOOC_TABLE_SCHEMA_HASH ||
        h->records_offset != SOOC_TABLE_HEADER_SIZE || h->capacity == 0 ||
        h->capacity > SOOC_TABLE_CAPACITY_MAX ||
        (uint64_t)h->records_offset + (uint64_t)h->capacity * SOOC_TABLE_RECORD_SIZE > size)
        return SOOC_TABLE_EVERSION;
    return SOOC_TABLE_OK;
}

static size_t table_bytes(uint32_t capacity) {
    return (size_t)SOOC_TABLE_HEADER_SIZE + (size_t)capacity * SOOC_TABLE_RECORD_SIZE;
}

/* --------------------------------------------------------------- reader */

struct sooc_table_reader {
    int fd;
    size_t size;
    const sooc_table_header *h;
    const sooc_table_record *recs;
    uint32_t cap;
};

int sooc_table_open_reader(const char *name, sooc_table_reader **out) {
    if (!out) return SOOC_TABLE_EINVAL;
    *out = NULL;
    char shm[SOOC_TABLE_NAME_MAX + 16];
    int rc = sooc_table_shm_name(name, shm, sizeof shm);
    if (rc) return rc;
    int fd = shm_open(shm, O_RDONLY, 0);
    if (fd < 0) return errno == ENOENT ? SOOC_TABLE_ENOENT : SOOC_TABLE_ESYS;
    struct stat st;
    if (fstat(fd, &st) != 0) goto sys_fail;
    if ((size_t)st.st_size < SOOC_TABLE_HEADER_SIZE) {
        close(fd);
        return SOOC_TABLE_ENOTREADY; /* created but not yet truncated to size */
    }
    size_t size = (size_t)st.st_size;
    void *base = mmap(NULL, size, PROT_READ, MAP_SHARED, fd, 0);
    if (base == MAP_FAILED) goto sys_fail;
    rc = check_header((const sooc_table_header *)base, size);
    if (rc) {
        munmap(base, size);
        close(fd);
        return rc;
    }
    sooc_table_reader *r = calloc(1, sizeof *r);
    if (!r) {
        munmap(base, size);
        close(fd);
        return SOOC_TABLE_ENOMEM;
    }
    r->fd = fd;
    r->size = size;
    r->h = (const sooc_table_header *)base;
    r->recs = (const sooc_table_record *)((const char *)base + r->h->records_offset);
    r->cap = r->h->capacity;
    *out = r;
    return SOOC_TABLE_OK;
sys_fail : {
    int e = errno;
    close(fd);
    errno = e;
    return SOOC_TABLE_ESYS;
}
}

void sooc_table_close_reader(sooc_table_reader *r) {
    if (!r) return;
    munmap((void *)r->h, r->size);
    close(r->fd);
    free(r);
}

uint64_t sooc_table_epoch(const sooc_table_reader *r) {
    return atomic_load_explicit(&r->h->table_seq, memory_order_acquire) / 2;
}

uint32_t sooc_table_capacity(const sooc_table_reader *r) { return r->cap; }

/* Per-record seqlock copy into w[32]; w[0] gets the (even) seq. */
static int read_slot_words(const sooc_table_record *src, uint64_t *w) {
    const aword *s = (const aword *)src;
    for (int t = 0; t < SOOC_TABLE_READ_RETRIES; t++) {
        uint64_t s0 = atomic_load_explicit(&s[0], memory_order_acquire);
        if (s0 & 1u) {
            cpu_relax();
            continue;
        }
        load_words(w + 1, s + 1, WORDS_PER_RECORD - 1);
        atomic_thread_fence(memory_order_acquire);
        uint64_t s1 = atomic_load_explicit(&s[0], memory_order_relaxed);
        if (s0 == s1) {
            w[0] = s0;
            return SOOC_TABLE_OK;
        }
        cpu_relax();
    }
    return SOOC_TABLE_EBUSY;
}

int sooc_table_read_record(sooc_table_reader *r, uint32_t slot, sooc_table_record *rec) {
    if (!r || !rec || slot >= r->cap) return SOOC_TABLE_EINVAL;
    uint64_t w[WORDS_PER_RECORD];
    int rc = read_slot_words(&r->recs[slot], w);
    if (rc == 0) memcpy((void *)rec, w, sizeof w);
    return rc;
}

static uint64_t bounded_high_water(const sooc_table_header *h, uint32_t cap) {
    uint64_t hw = atomic_load_explicit(&h->high_water, memory_order_relaxed);
    return hw > cap ? cap : hw;
}

int sooc_table_find(sooc_table_reader *r, uint64_t object_id, sooc_table_record *rec) {
    if (!r || !rec || object_id == 0) return SOOC_TABLE_EINVAL;
    uint64_t hw = bounded_high_water(r->h, r->cap);
    int busy = 0;
    for (uint64_t i = 0; i < hw; i++) {
        /* cheap pre-filter on the id word, then a validated copy */
        const aword *s = (const aword *)&r->recs[i];
        if (atomic_load_explicit(&s[1], memory_order_relaxed) != object_id) continue;
        uint64_t w[WORDS_PER_RECORD];
        int rc = read_slot_words(&r->recs[i], w);
        if (rc) {
            busy = 1;
            continue;
        }
        if (w[1] == object_id) {
            memcpy((void *)rec, w, sizeof w);
            return SOOC_TABLE_OK;
        }
    }
    return busy ? SOOC_TABLE_EBUSY : SOOC_TABLE_ENOENT;
}

/* Wait out an odd table_seq: spin a little, then sleep, within the retry bound. */
static void table_backoff(int attempt) {
    if (attempt < 8)
        sched_yield();
    else
        sleep_ns(SNAPSHOT_SLEEP_NS);
}

int sooc_table_snapshot(sooc_table_reader *r, sooc_table_record *out, uint32_t cap, uint32_t *n,
                        uint64_t *epoch) {
    if (!r || !n || (!out && cap)) return SOOC_TABLE_EINVAL;
    const aword *ts = &r->h->table_seq;
    for (int t = 0; t < SOOC_TABLE_READ_RETRIES; t++) {
        uint64_t s0 = atomic_load_explicit(ts, memory_order_acquire);
        if (s0 & 1u) {
            table_backoff(t);
            continue;
        }
        uint64_t hw = bounded_high_water(r->h, r->cap);
        uint32_t cnt = 0;
        for (uint64_t i = 0; i < hw; i++) {
            const aword *src = (const aword *)&r->recs[i];
            uint64_t id = atomic_load_explicit(&src[1], memory_order_relaxed);
            if (id == 0) continue;
            if (cnt < cap) {
                uint64_t w[WORDS_PER_RECORD];
                load_words(w, src, WORDS_PER_RECORD);
                w[1] = id;
                memcpy((void *)&out[cnt], w, sizeof w);
            }
            cnt++;
        }
        atomic_thread_fence(memory_order_acquire);
        uint64_t s1 = atomic_load_explicit(ts, memory_order_relaxed);
        if (s0 == s1) {
            *n = cnt;
            if (epoch) *epoch = s0 / 2;
            return cnt > cap ? SOOC_TABLE_ERANGE : SOOC_TABLE_OK;
        }
        table_backoff(t);
    }
    return SOOC_TABLE_EBUSY;
}

int sooc_table_get_info(sooc_table_reader *r, sooc_table_info *info) {
    if (!r || !info) return SOOC_TABLE_EINVAL;
    const sooc_table_header *h = r->h;
    for (int t = 0; t < SOOC_TABLE_READ_RETRIES; t++) {
        uint64_t s0 = atomic_load_explicit(&h->table_seq, memory_order_acquire);
        if (s0 & 1u) {
            table_backoff(t);
            continue;
        }
        uint64_t meta[META_WORDS];
        load_words(meta, (const char *)h + META_OFF, META_WORDS);
        sooc_table_info in;
        memset(&in, 0, sizeof in);
        in.high_water = atomic_load_explicit(&h->high_water, memory_order_relaxed);
        in.n_objects = atomic_load_explicit(&h->n_objects, memory_order_relaxed);
        atomic_thread_fence(memory_order_acquire);
        if (atomic_load_explicit(&h->table_seq, memory_order_relaxed) != s0) {
            table_backoff(t);
            continue;
        }
        /* the batch block, decoded from the private copy */
        memcpy(&in.latent_dim, (const char *)meta + (256 - META_OFF), 4);
        memcpy(&in.latent_model_id, (const char *)meta + (264 - META_OFF), 8);
        memcpy(&in.stamp_ns, (const char *)meta + (272 - META_OFF), 8);
        memcpy(in.T_src_map, (const char *)meta + (280 - META_OFF), sizeof in.T_src_map);
        /* write-once fields and independent atomics */
        in.capacity = h->capacity;
        in.abi_minor = h->abi_minor;
        in.created_real_ns = h->created_real_ns;
        memcpy(in.frame_id, h->frame_id, sizeof in.frame_id);
        in.frame_id[sizeof in.frame_id - 1] = 0;
        in.epoch = s0 / 2;
        in.instance_id = atomic_load_explicit(&h->instance_id, memory_order_relaxed);
        in.writer_pid = atomic_load_explicit(&h->writer_pid, memory_order_relaxed);
        in.hflags = atomic_load_explicit(&h->hflags, memory_order_relaxed);
        in.heartbeat_mono_ns = atomic_load_explicit(&h->heartbeat_mono_ns, memory_order_relaxed);
        *info = in;
        return SOOC_TABLE_OK;
    }
    return SOOC_TABLE_EBUSY;
}

/* The store block: words 152..184, under store_seq. */
#define STORE_OFF 152
#define STORE_WORDS 4

int sooc_table_get_store(sooc_table_reader *r, sooc_table_store *out) {
    if (!r || !out) return SOOC_TABLE_EINVAL;
    const sooc_table_header *h = r->h;
    memset(out, 0, sizeof *out);
    if (h->abi_minor < 1) return SOOC_TABLE_OK;
    for (int t = 0; t < SOOC_TABLE_READ_RETRIES; t++) {
        uint64_t s0 = atomic_load_explicit(&h->store_seq, memory_order_acquire), w[STORE_WORDS];
        if (s0 & 1u) {
            table_backoff(t);
            continue;
        }
        load_words(w, (const char *)h + STORE_OFF, STORE_WORDS);
        atomic_thread_fence(memory_order_acquire);
        if (atomic_load_explicit(&h->store_seq, memory_order_relaxed) != s0) continue;
        memcpy(&out->state, (const char *)w, 4);
        memcpy(&out->fault, (const char *)w + 4, 4);
        memcpy(&out->pending, &w[1], 8);
        memcpy(&out->pending_kf, &w[2], 8);
        memcpy(&out->committed_ns, &w[3], 8);
        return SOOC_TABLE_OK;
    }
    return SOOC_TABLE_EBUSY;
}

int sooc_table_writer_alive(sooc_table_reader *r, sooc_table_liveness *live) {
    if (!r) return SOOC_TABLE_EINVAL;
    sooc_table_liveness L;
    memset(&L, 0, sizeof L);
    /* The writer holds LOCK_EX on its own open file description; our shared
     * non-blocking request fails with EWOULDBLOCK exactly while it lives. */
    if (flock(r->fd, LOCK_SH | LOCK_NB) == 0) {
        flock(r->fd, LOCK_UN);
        L.lock_held = 0;
    } else if (errno == EWOULDBLOCK || errno == EAGAIN) {
        L.lock_held = 1;
    } else {
        return SOOC_TABLE_ESYS;
    }
    const sooc_table_header *h = r->h;
    L.exited = (atomic_load_explicit(&h->hflags, memory_order_acquire) &
                SOOC_TABLE_HFLAG_WRITER_EXITED) != 0;
    L.heartbeat_age_ns =
        mono_ns() - atomic_load_explicit(&h->heartbeat_mono_ns, memory_order_relaxed);
    L.instance_id = atomic_load_explicit(&h->instance_id, memory_order_relaxed);
    L.writer_pid = atomic_load_explicit(&h->writer_pid, memory_order_relaxed);
    if (live) *live = L;
    return L.lock_held && !L.exited && L.heartbeat_age_ns < SOOC_TABLE_HEARTBEAT_STALE_NS;
}

/* --------------------------------------------------------------- writer */

struct sooc_table_writer {
    int fd;
    size_t size;
    sooc_table_header *h;
    sooc_table_record *recs;
    uint32_t cap;
    char shm[SOOC_TABLE_NAME_MAX + 16];

    int in_batch;
    uint64_t batch_odd;   /* table_seq value during the open batch */
    uint64_t batch_epoch; /* epoch the open batch will publish */
    uint64_t hw;          /* private copy of high_water */
    uint32_t n_live;      /* objects in the table that are not REMOVED */

    /* object_id -> slot: open addressing, linear probing, backward-shift delete */
    uint64_t *keys;
    uint32_t *vals;
    uint32_t mask;

    uint64_t *slot_id;      /* object_id held by each slot (0 = empty) */
    uint64_t *removed_at;   /* epoch of removal, 0 = not removed */
    uint32_t *free_slots;   /* empty slots below hw (stack) */
    uint32_t n_free;
    uint32_t *rq_slot;      /* FIFO of removed slots, by removal epoch */
    uint64_t *rq_epoch;
    uint32_t rq_head, rq_len;
    uint8_t *rq_seen; /* scratch bitmap for rq_compact */

    pthread_t hb_thread;
    int hb_running;
    int hb_stop;
    long hb_period_ns;
    pthread_mutex_t hb_mu;
    pthread_cond_t hb_cv;
};

static inline uint64_t hash64(uint64_t k) {
    k ^= k >> 33;
    k *= 0xff51afd7ed558ccdull;
    k ^= k >> 33;
    k *= 0xc4ceb9fe1a85ec53ull;
    k ^= k >> 33;
    return k;
}

static int64_t map_get(const sooc_table_writer *w, uint64_t key) {
    for (uint32_t i = (uint32_t)hash64(key) & w->mask;; i = (i + 1) & w->mask) {
        if (w->keys[i] == key) return w->vals[i];
        if (w->keys[i] == 0) return -1;
    }
}

static void map_put(sooc_table_writer *w, uint64_t key, uint32_t slot) {
    uint32_t i = (uint32_t)hash64(key) & w->mask;
    while (w->keys[i] != 0 && w->keys[i] != key) i = (i + 1) & w->mask;
    w->keys[i] = key;
    w->vals[i] = slot;
}

static void map_del(sooc_table_writer *w, uint64_t key) {
    uint32_t i = (uint32_t)hash64(key) & w->mask;
    while (w->keys[i] != key) {
        if (w->keys[i] == 0) return;
        i = (i + 1) & w->mask;
    }
    /* backward-shift deletion keeps probe chains intact without tombstones */
    uint32_t j = i;
    for (;;) {
        w->keys[i] = 0;
        for (;;) {
            j = (j + 1) & w->mask;
            if (w->keys[j] == 0) return;
            uint32_t home = (uint32_t)hash64(w->keys[j]) & w->mask;
            /* move j back to i unless its home lies cyclically in (i, j] */
            if (i <= j ? (i < home && home <= j) : (i < home || home <= j)) continue;
            break;
        }
        w->keys[i] = w->keys[j];
        w->vals[i] = w->vals[j];
        i = j;
    }
}

/* Write one record under its seqlock (writer side). */
static void write_slot_words(sooc_table_record *dst, const uint64_t *w) {
    aword *d = (aword *)dst;
    uint64_t s = atomic_load_explicit(&d[0], memory_order_relaxed);
    uint64_t odd = (s & 1u) ? s + 2 : s + 1; /* odd even after a crash left it odd */
    atomic_store_explicit(&d[0], odd, memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    store_words(d + 1, w + 1, WORDS_PER_RECORD - 1);
    atomic_store_explicit(&d[0], odd + 1, memory_order_release);
}

static void clear_slot(sooc_table_writer *w, uint32_t slot) {
    uint64_t z[WORDS_PER_RECORD];
    memset(z, 0, sizeof z);
    write_slot_words(&w->recs[slot], z);
}

static void begin_batch_raw(sooc_table_writer *w) {
    uint64_t s = atomic_load_explicit(&w->h->table_seq, memory_order_relaxed);
    w->batch_odd = (s & 1u) ? s + 2 : s + 1;
    w->batch_epoch = w->batch_odd / 2 + 1;
    atomic_store_explicit(&w->h->table_seq, w->batch_odd, memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    w->in_batch = 1;
}

static void end_batch_raw(sooc_table_writer *w) {
    atomic_store_explicit(&w->h->high_water, w->hw, memory_order_relaxed);
    atomic_store_explicit(&w->h->n_objects, w->n_live, memory_order_relaxed);
    atomic_store_explicit(&w->h->table_seq, w->batch_odd + 1, memory_order_release);
    w->in_batch = 0;
}

/* Drop stale entries (slot resurrected or re-removed later) and duplicates.
 * Afterwards each slot appears at most once, so rq_len <= capacity. */
static void rq_compact(sooc_table_writer *w) {
    memset(w->rq_seen, 0, ((size_t)w->cap + 7) / 8);
    uint32_t n = 0;
    for (uint32_t k = 0; k < w->rq_len; k++) {
        uint32_t i = (w->rq_head + k) % w->cap;
        uint32_t slot = w->rq_slot[i];
        uint64_t e = w->rq_epoch[i];
        if (w->removed_at[slot] != e || (w->rq_seen[slot / 8] & (1u << (slot % 8)))) continue;
        w->rq_seen[slot / 8] |= (uint8_t)(1u << (slot % 8));
        uint32_t j = (w->rq_head + n) % w->cap;
        w->rq_slot[j] = slot;
        w->rq_epoch[j] = e;
        n++;
    }
    w->rq_len = n;
}

static void rq_push(sooc_table_writer *w, uint32_t slot, uint64_t epoch) {
    /* Entries of resurrected slots go stale; a writer that clears and
     * re-inserts every batch would fill the ring with them, so compact. */
    if (w->rq_len == w->cap) rq_compact(w);
    if (w->rq_len == w->cap) { /* cannot happen: each slot is live at most once */
        w->rq_head = (w->rq_head + 1) % w->cap;
        w->rq_len--;
    }
    uint32_t k = (w->rq_head + w->rq_len) % w->cap;
    w->rq_slot[k] = slot;
    w->rq_epoch[k] = epoch;
    w->rq_len++;
}

/* Take a REMOVED slot whose removal is at least `delay` epochs old, or -1. */
static int64_t rq_take(sooc_table_writer *w, uint64_t delay) {
    while (w->rq_len) {
        uint32_t slot = w->rq_slot[w->rq_head];
        uint64_t e = w->rq_epoch[w->rq_head];
        if (w->removed_at[slot] != e) { /* stale: resurrected or already reclaimed */
            w->rq_head = (w->rq_head + 1) % w->cap;
            w->rq_len--;
            continue;
        }
        if (e + delay > w->batch_epoch) return -1; /* FIFO: the rest are younger */
        w->rq_head = (w->rq_head + 1) % w->cap;
        w->rq_len--;
        map_del(w, w->slot_id[slot]);
        w->slot_id[slot] = 0;
        w->removed_at[slot] = 0;
        return slot;
    }
    return -1;
}

static int64_t alloc_slot(sooc_table_writer *w) {
    if (w->n_free) return w->free_slots[--w->n_free];
    int64_t s = rq_take(w, REUSE_EPOCHS);
    if (s >= 0) return s;
    if (w->hw < w->cap) {
        /* publish the new bound at once: per-record readers see the object
         * before the batch ends, and a restart after a crash finds it */
        w->hw++;
        atomic_store_explicit(&w->h->high_water, w->hw, memory_order_release);
        return (int64_t)(w->hw - 1);
    }
    return rq_take(w, 1); /* full: reuse anything published as removed for one epoch */
}

static int writer_alloc_state(sooc_table_writer *w) {
    uint32_t m = 16;
    while (m < 2u * w->cap) m <<= 1;
    w->mask = m - 1;
    w->keys = calloc(m, sizeof *w->keys);
    w->vals = calloc(m, sizeof *w->vals);
    w->slot_id = calloc(w->cap, sizeof *w->slot_id);
    w->removed_at = calloc(w->cap, sizeof *w->removed_at);
    w->free_slots = calloc(w->cap, sizeof *w->free_slots);
    w->rq_slot = calloc(w->cap, sizeof *w->rq_slot);
    w->rq_epoch = calloc(w->cap, sizeof *w->rq_epoch);
    w->rq_seen = calloc(((size_t)w->cap + 7) / 8, 1);
    if (!w->keys || !w->vals || !w->slot_id || !w->removed_at || !w->free_slots || !w->rq_slot ||
        !w->rq_epoch || !w->rq_seen)
        return SOOC_TABLE_ENOMEM;
    return SOOC_TABLE_OK;
}

static void writer_free(sooc_table_writer *w) {
    if (!w) return;
    free(w->keys);
    free(w->vals);
    free(w->slot_id);
    free(w->removed_at);
    free(w->free_slots);
    free(w->rq_slot);
    free(w->rq_epoch);
    free(w->rq_seen);
    if (w->h) munmap(w->h, w->size);
    if (w->fd >= 0) close(w->fd); /* releases the flock */
    free(w);
}

static uint64_t new_instance_id(void) {
    uint64_t v = 0;
    if (getrandom(&v, sizeof v, GRND_NONBLOCK) != (ssize_t)sizeof v || v == 0)
        v = hash64((uint64_t)mono_ns() ^ ((uint64_t)getpid() << 32) ^ (uint64_t)real_ns());
    return v ? v : 1;
}

/* Take the writer lock. A reader's liveness probe holds LOCK_SH for a few
 * microseconds, so retry for about 100 ms before declaring another writer. */
static int take_writer_lock(int fd) {
    for (int i = 0; i < 100; i++) {
        if (flock(fd, LOCK_EX | LOCK_NB) == 0) return SOOC_TABLE_OK;
        if (errno != EWOULDBLOCK && errno != EAGAIN && errno != EINTR) return SOOC_TABLE_ESYS;
        sleep_ns(1000000L);
    }
    return SOOC_TABLE_ELOCKED;
}

/* Fill a brand-new header; magic goes last with release. */
static void init_header(sooc_table_writer *w, const char *frame_id) {
    sooc_table_header *h = w->h;
    memset((char *)h + 8, 0, SOOC_TABLE_HEADER_SIZE - 8);
    h->abi_major = SOOC_TABLE_ABI_MAJOR;
    h->abi_minor = SOOC_TABLE_ABI_MINOR;
    h->header_size = SOOC_TABLE_HEADER_SIZE;
    h->record_size = SOOC_TABLE_RECORD_SIZE;
    h->capacity = w->cap;
    h->records_offset = SOOC_TABLE_HEADER_SIZE;
    h->schema_hash = SOOC_TABLE_SCHEMA_HASH;
    strncpy(h->frame_id, frame_id, sizeof h->frame_id - 1);
    h->latent_max = SOOC_TABLE_LATENT_MAX;
    h->created_real_ns = real_ns();
    h->store_committed_ns = INT64_MIN;   /* store block: no database state yet */
    for (int i = 0; i < 4; i++) h->T_src_map[i * 5] = 1.0; /* identity */
    atomic_store_explicit(&h->instance_id, new_instance_id(), memory_order_relaxed);
    atomic_store_explicit(&h->writer_pid, (int64_t)getpid(), memory_order_relaxed);
    atomic_store_explicit(&h->heartbeat_mono_ns, mono_ns(), memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    atomic_store_explicit(&h->magic, SOOC_TABLE_MAGIC, memory_order_release);
}

/* Take over a compatible table left by an earlier writer: clear records left
 * odd (torn), re-register the others, renew the instance id. One batch. */
static void adopt_table(sooc_table_writer *w) {
    sooc_table_header *h = w->h;
    static const sooc_table_store none = {SOOC_TABLE_STORE_NONE, 0, 0, 0, INT64_MIN};
    sooc_table_set_store(w, &none);   /* this writer's database says its state itself */
    h->abi_minor = SOOC_TABLE_ABI_MINOR;
    atomic_store_explicit(&h->instance_id, new_instance_id(), memory_order_relaxed);
    atomic_store_explicit(&h->writer_pid, (int64_t)getpid(), memory_order_relaxed);
    atomic_store_explicit(&h->heartbeat_mono_ns, mono_ns(), memory_order_relaxed);
    atomic_fetch_and_explicit(&h->hflags, ~(uint64_t)SOOC_TABLE_HFLAG_WRITER_EXITED,
                              memory_order_release);
    begin_batch_raw(w); /* makes an odd table_seq of a dead writer move on */
    w->hw = bounded_high_water(h, w->cap);
    w->n_live = 0;
    for (uint32_t i = 0; i < w->hw; i++) {
        aword *s = (aword *)&w->recs[i];
        uint64_t seq = atomic_load_explicit(&s[0], memory_order_relaxed);
        uint64_t id = atomic_load_explicit(&s[1], memory_order_relaxed);
        uint32_t flags = w->recs[i].flags;
        if ((seq & 1u) || (id != 0 && map_get(w, id) >= 0)) {
            clear_slot(w, i); /* torn by a crash, or a duplicate id */
            id = 0;
        }
        if (id == 0) {
            w->free_slots[w->n_free++] = i;
            continue;
        }
        map_put(w, id, i);
        w->slot_id[i] = id;
        if (flags & SOOC_TABLE_FLAG_REMOVED) {
            w->removed_at[i] = w->batch_epoch;
            rq_push(w, i, w->batch_epoch);
        } else {
            w->n_live++;
        }
    }
    /* hand out low slots first */
    for (uint32_t a = 0, b = w->n_free; a + 1 < b; a++, b--) {
        uint32_t t = w->free_slots[a];
        w->free_slots[a] = w->free_slots[b - 1];
        w->free_slots[b - 1] = t;
    }
    end_batch_raw(w);
}

int sooc_table_create_writer(const char *name, uint32_t capacity, uint32_t mode,
                             const char *frame_id, sooc_table_writer **out) {
    if (!out) return SOOC_TABLE_EINVAL;
    *out = NULL;
    if (!frame_id) frame_id = "map";
    if (capacity == 0 || capacity > SOOC_TABLE_CAPACITY_MAX || (mode & ~0777u) ||
        strlen(frame_id) >= sizeof(((sooc_table_header *)0)->frame_id))
        return SOOC_TABLE_EINVAL;
    if (mode == 0) mode = SOOC_TABLE_DEFAULT_MODE;
    mode |= 0600u; /* the writer itself needs read-write */
    sooc_table_writer *w = calloc(1, sizeof *w);
    if (!w) return SOOC_TABLE_ENOMEM;
    w->fd = -1;
    w->cap = capacity;
    int rc = sooc_table_shm_name(name, w->shm, sizeof w->shm);
    if (rc) goto fail;
    rc = writer_alloc_state(w);
    if (rc) goto fail;
    w->size = table_bytes(capacity);

    int adopt = 0;
    for (int attempt = 0; attempt < 2; attempt++) {
        w->fd = shm_open(w->shm, O_RDWR | O_CREAT, 0600);
        if (w->fd < 0) goto sys_fail;
        rc = take_writer_lock(w->fd);
        if (rc) goto fail;
        struct stat st;
        if (fstat(w->fd, &st) != 0) goto sys_fail;
        if (st.st_size == 0) break; /* fresh object (ours, or abandoned before ftruncate) */
        if ((size_t)st.st_size == w->size) {
            void *p = mmap(NULL, w->size, PROT_READ, MAP_SHARED, w->fd, 0);
            if (p == MAP_FAILED) goto sys_fail;
            const sooc_table_header *h = p;
            uint64_t magic = atomic_load_explicit(&h->magic, memory_order_acquire);
            int ok = check_header(h, w->size) == 0 && h->capacity == capacity &&
                     strncmp(h->frame_id, frame_id, sizeof h->frame_id) == 0;
            munmap(p, w->size);
            if (ok) {
                adopt = 1;
                break;
            }
            if (magic == 0) break; /* creator died before publishing: re-initialise */
        }
        /* Incompatible: unlink and create anew. Readers of the old object keep
         * their mapping and see its writer as dead once we close this fd. */
        if (attempt == 1) {
            rc = SOOC_TABLE_ELOCKED; /* someone recreated it meanwhile */
            goto fail;
        }
        shm_unlink(w->shm);
        close(w->fd);
        w->fd = -1;
    }
    /* fchmod so the umask does not narrow the mode planners need */
    if (fchmod(w->fd, (mode_t)mode) != 0) goto sys_fail;
    if (!adopt && ftruncate(w->fd, (off_t)w->size) != 0) goto sys_fail;
    void *base = mmap(NULL, w->size, PROT_READ | PROT_WRITE, MAP_SHARED, w->fd, 0);
    if (base == MAP_FAILED) goto sys_fail;
    w->h = base;
    w->recs = (sooc_table_record *)((char *)base + SOOC_TABLE_HEADER_SIZE);
    if (adopt) {
        adopt_table(w);
    } else {
        /* a fresh ftruncate gives zeros, but a re-initialised object may not */
        memset(w->recs, 0, (size_t)capacity * SOOC_TABLE_RECORD_SIZE);
        atomic_store_explicit(&w->h->magic, 0, memory_order_relaxed);
        init_header(w, frame_id);
    }
    *out = w;
    return SOOC_TABLE_OK;
sys_fail:
    rc = SOOC_TABLE_ESYS;
fail : {
    int e = errno;
    writer_free(w);
    errno = e;
    return rc;
}
}

int sooc_table_begin_batch(sooc_table_writer *w) {
    if (!w) return SOOC_TABLE_EINVAL;
    if (w->in_batch) return SOOC_TABLE_ESTATE;
    begin_batch_raw(w);
    return SOOC_TABLE_OK;
}

int sooc_table_end_batch(sooc_table_writer *w) {
    if (!w) return SOOC_TABLE_EINVAL;
    if (!w->in_batch) return SOOC_TABLE_ESTATE;
    end_batch_raw(w);
    return SOOC_TABLE_OK;
}

int sooc_table_upsert(sooc_table_writer *w, const sooc_table_record *rec) {
    if (!w || !rec || rec->object_id == 0 || rec->latent_dim > SOOC_TABLE_LATENT_MAX)
        return SOOC_TABLE_EINVAL;
    if (!w->in_batch) return SOOC_TABLE_ESTATE;
    int64_t slot = map_get(w, rec->object_id);
    if (slot < 0) {
        slot = alloc_slot(w);
        if (slot < 0) return SOOC_TABLE_EFULL;
        map_put(w, rec->object_id, (uint32_t)slot);
        w->slot_id[slot] = rec->object_id;
        w->n_live++;
    } else if (w->removed_at[slot]) { /* resurrected before its slot was reused */
        w->removed_at[slot] = 0;
        w->n_live++;
    }
    uint64_t words[WORDS_PER_RECORD];
    memcpy(words, (const void *)rec, sizeof words);
    write_slot_words(&w->recs[slot], words);
    return SOOC_TABLE_OK;
}

static void remove_slot(sooc_table_writer *w, uint32_t slot) {
    union {
        uint64_t w[WORDS_PER_RECORD];
        struct { uint64_t seq, id; uint32_t flags; } f;
    } u;
    load_words(u.w, &w->recs[slot], WORDS_PER_RECORD); /* our own data: no race */
    u.f.flags = (u.f.flags | SOOC_TABLE_FLAG_REMOVED) & ~SOOC_TABLE_FLAG_VALID;
    write_slot_words(&w->recs[slot], u.w);
    w->removed_at[slot] = w->batch_epoch;
    rq_push(w, slot, w->batch_epoch);
    w->n_live--;
}

int sooc_table_remove(sooc_table_writer *w, uint64_t object_id) {
    if (!w || object_id == 0) return SOOC_TABLE_EINVAL;
    if (!w->in_batch) return SOOC_TABLE_ESTATE;
    int64_t slot = map_get(w, object_id);
    if (slot < 0 || w->removed_at[slot]) return SOOC_TABLE_ENOENT;
    remove_slot(w, (uint32_t)slot);
    return SOOC_TABLE_OK;
}

int sooc_table_clear(sooc_table_writer *w) {
    if (!w) return SOOC_TABLE_EINVAL;
    if (!w->in_batch) return SOOC_TABLE_ESTATE;
    for (uint32_t i = 0; i < w->hw; i++)
        if (w->slot_id[i] && !w->removed_at[i]) remove_slot(w, i);
    return SOOC_TABLE_OK;
}

int sooc_table_set_meta(sooc_table_writer *w, uint32_t latent_dim, uint64_t latent_model_id,
                        int64_t stamp_ns, const double T_src_map[16]) {
    if (!w || latent_dim > SOOC_TABLE_LATENT_MAX) return SOOC_TABLE_EINVAL;
    if (!w->in_batch) return SOOC_TABLE_ESTATE;
    uint64_t meta[META_WORDS];
    load_words(meta, (char *)w->h + META_OFF, META_WORDS);
    char *m = (char *)meta;
    memcpy(m + (256 - META_OFF), &latent_dim, 4);
    memcpy(m + (264 - META_OFF), &latent_model_id, 8);
    memcpy(m + (272 - META_OFF), &stamp_ns, 8);
    if (T_src_map) memcpy(m + (280 - META_OFF), T_src_map, 16 * sizeof(double));
    store_words((char *)w->h + META_OFF, meta, META_WORDS);
    if (T_src_map)
        atomic_fetch_or_explicit(&w->h->hflags, SOOC_TABLE_HFLAG_FLOOR_SET, memory_order_relaxed);
    return SOOC_TABLE_OK;
}

int sooc_table_set_store(sooc_table_writer *w, const sooc_table_store *st) {
    if (!w || !st) return SOOC_TABLE_EINVAL;
    uint64_t v[STORE_WORDS];
    memcpy((char *)v, &st->state, 4);
    memcpy((char *)v + 4, &st->fault, 4);
    memcpy(&v[1], &st->pending, 8);
    memcpy(&v[2], &st->pending_kf, 8);
    memcpy(&v[3], &st->committed_ns, 8);
    uint64_t s0 = atomic_load_explicit(&w->h->store_seq, memory_order_relaxed);
    atomic_store_explicit(&w->h->store_seq, s0 + 1, memory_order_relaxed);
    atomic_thread_fence(memory_order_release);
    store_words((char *)w->h + STORE_OFF, v, STORE_WORDS);
    atomic_store_explicit(&w->h->store_seq, s0 + 2, memory_order_release);
    return SOOC_TABLE_OK;
}

void sooc_table_heartbeat(sooc_table_writer *w) {
    if (w) atomic_store_explicit(&w->h->heartbeat_mono_ns, mono_ns(), memory_order_release);
}

static void *heartbeat_main(void *arg) {
    sooc_table_writer *w = arg;
    struct timespec next;
    clock_gettime(CLOCK_MONOTONIC, &next);
    pthread_mutex_lock(&w->hb_mu);
    while (!w->hb_stop) {
        sooc_table_heartbeat(w);
        next.tv_nsec += w->hb_period_ns;
        while (next.tv_nsec >= 1000000000L) {
            next.tv_nsec -= 1000000000L;
            next.tv_sec++;
        }
        while (!w->hb_stop && pthread_cond_timedwait(&w->hb_cv, &w->hb_mu, &next) == 0) {
        }
    }
    pthread_mutex_unlock(&w->hb_mu);
    return NULL;
}

int sooc_table_start_heartbeat(sooc_table_writer *w, double hz) {
    if (!w || hz < 0 || (hz > 0 && hz < 1.0) || hz > 1000.0) return SOOC_TABLE_EINVAL;
    if (w->hb_running) return SOOC_TABLE_ESTATE;
    if (hz == 0) hz = 20.0;
    w->hb_period_ns = (long)(1e9 / hz);
    w->hb_stop = 0;
    pthread_condattr_t ca;
    pthread_condattr_init(&ca);
    pthread_condattr_setclock(&ca, CLOCK_MONOTONIC);
    int e1 = pthread_mutex_init(&w->hb_mu, NULL);
    int e2 = pthread_cond_init(&w->hb_cv, &ca);
    pthread_condattr_destroy(&ca);
    if (e1 || e2) {
        if (!e1) pthread_mutex_destroy(&w->hb_mu);
        if (!e2) pthread_cond_destroy(&w->hb_cv);
        errno = e1 ? e1 : e2;
        return SOOC_TABLE_ESYS;
    }
    int e = pthread_create(&w->hb_thread, NULL, heartbeat_main, w);
    if (e) {
        pthread_mutex_destroy(&w->hb_mu);
        pthread_cond_destroy(&w->hb_cv);
        errno = e;
        return SOOC_TABLE_ESYS;
    }
    w->hb_running = 1;
    return SOOC_TABLE_OK;
}

void sooc_table_stop_heartbeat(sooc_table_writer *w) {
    if (!w || !w->hb_running) return;
    pthread_mutex_lock(&w->hb_mu);
    w->hb_stop = 1;
    pthread_cond_signal(&w->hb_cv);
    pthread_mutex_unlock(&w->hb_mu);
    pthread_join(w->hb_thread, NULL);
    pthread_mutex_destroy(&w->hb_mu);
    pthread_cond_destroy(&w->hb_cv);
    w->hb_running = 0;
}

int sooc_table_close_writer(sooc_table_writer *w, int unlink) {
    if (!w) return SOOC_TABLE_OK;
    sooc_table_stop_heartbeat(w);
    if (w->in_batch) end_batch_raw(w);
    sooc_table_heartbeat(w);
    atomic_fetch_or_explicit(&w->h->hflags, SOOC_TABLE_HFLAG_WRITER_EXITED, memory_order_release);
    int rc = SOOC_TABLE_OK;
    if (unlink && shm_unlink(w->shm) != 0) rc = SOOC_TABLE_ESYS;
    int e = errno;
    writer_free(w); /* munmap, close: the kernel drops the flock */
    errno = e;
    return rc;
}

uint64_t sooc_table_writer_epoch(const sooc_table_writer *w) {
    return atomic_load_explicit(&w->h->table_seq, memory_order_relaxed) / 2;
}

uint64_t sooc_table_writer_instance(const sooc_table_writer *w) {
    return atomic_load_explicit(&w->h->instance_id, memory_order_relaxed);
}

uint32_t sooc_table_writer_count(const sooc_table_writer *w) { return w->n_live; }

