/* Private structures of the log readers (src/logs): the one message index
 * both container formats fill, and the helpers they share. */
#ifndef SOOC3D_LOGS_IMPL_H
#define SOOC3D_LOGS_IMPL_H

#include "sooc3d/log.h"

#include <stdint.h>
#include <string.h>

/* chunk compressions */
enum { LOGS_COMP_NONE = 0, LOGS_COMP_LZ4 = 1, LOGS_COMP_BZ2 = 2, LOGS_COMP_ZSTD = 3 };

/* Largest chunk or unchunked record this reader decompresses or loads. */
#define LOGS_MAX_RECORD ((uint64_t)1 << 30)

typedef struct sooc_logs_chunk {
    uint64_t pos;              /* file offset of the chunk record                          */
    uint64_t data_off;         /* file offset of its (compressed) records                  */
    uint64_t csize, usize;     /* compressed and uncompressed sizes                        */
    uint32_t crc;              /* MCAP: CRC-32 of the uncompressed records (0 = none)      */
    int comp;
    int scanned;               /* its records were walked at open                          */
} sooc_logs_chunk;

typedef struct sooc_logs_entry {
    int64_t t;                 /* log time                                                 */
    uint64_t off;              /* offset in the uncompressed chunk, or the file offset of
                                  an unchunked record (chunk = -1)                         */
    int32_t chunk;
    int32_t ch;                /* channel index                                            */
} sooc_logs_entry;

typedef struct sooc_logs_chan {
    sooc_logfile_channel pub;
    uint32_t file_id;          /* bag conn id / MCAP channel id                            */
    int schema;                /* MCAP schema id (0 none)                                  */
    char *topic, *type, *encoding, *definition;
    int64_t *msgs, nmsgs;      /* positions in the sorted entries                          */
} sooc_logs_chan;

typedef struct sooc_logs_schema {
    uint16_t id;
    char *name, *encoding, *data;
} sooc_logs_schema;

typedef struct sooc_logs_slot {     /* one decompressed chunk                                   */
    int32_t chunk;
    uint64_t stamp;            /* LRU clock                                                */
    uint8_t *buf;
    size_t cap;
} sooc_logs_slot;

struct sooc_logfile {
    char *path;
    int fd;
    sooc_logfile_kind kind;
    uint64_t size;
    int indexed;
    sooc_logs_chan *ch;
    int64_t nch, capch;
    sooc_logs_schema *sc;
    int64_t nsc, capsc;
    sooc_logs_chunk *chunks;
    int64_t nchunks, capchunks;
    sooc_logs_entry *e;
    int64_t ne, cape;
    unsigned comp_seen;        /* bit per LOGS_COMP_*                                      */
    sooc_logs_slot slot[2];
    uint64_t clock;
    uint8_t *raw;              /* compressed bytes / an unchunked record                   */
    size_t rawcap;
    /* MCAP */
    uint64_t data_end;         /* offset of the Data End record (0: unknown)               */
    uint32_t data_crc;         /* its data_section_crc                                     */
    uint64_t summary_start, footer_pos;
    uint32_t summary_crc;
};

/* ---- shared helpers (logfile.c) ---- */
/* |a - b| in ns, saturated at INT64_MAX: a log's stamps may be anything, and their difference must not
 * overflow */
static inline int64_t logs_tgap(int64_t a, int64_t b) {
    uint64_t d = a > b ? (uint64_t)a - (uint64_t)b : (uint64_t)b - (uint64_t)a;
    return d > (uint64_t)INT64_MAX ? INT64_MAX : (int64_t)d;
}
static inline uint16_t logs_u16(const uint8_t *p) { return (uint16_t)(p[0] | (p[1] << 8)); }
static inline uint32_t logs_u32(const uint8_t *p) {
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}
static inline uint64_t logs_u64(const uint8_t *p) { return (uint64_t)logs_u32(p) | ((uint64_t)logs_u32(p + 4) << 32); }

/* pread exactly n bytes at off; EFORMAT naming the offset when the file ends first. */
sooc_status sooc_logs_pread(sooc_logfile *lf, uint64_t off, void *buf, size_t n, const char *what);
/* EFORMAT: the record at byte i of the n-byte chunk at file offset where is cut short. */
sooc_status sooc_logs_chunk_cut(const sooc_logfile *lf, uint64_t where, size_t i, size_t n);
/* A NUL-terminated copy of n bytes (sooc_malloc). */
char *sooc_logs_dupn(const char *s, size_t n);
/* Grow the array *p of *cap elements of elem bytes to hold need (doubling). */
sooc_status sooc_logs_grow(void **p, int64_t *cap, int64_t need, size_t elem, const char *path);
/* Grow *buf to at least n bytes. */
sooc_status sooc_logs_reserve(uint8_t **buf, size_t *cap, size_t n);
/* Add a channel (strings copied); *index gets its position. */
sooc_status sooc_logs_add_channel(sooc_logfile *lf, uint32_t file_id, const char *topic, size_t ntopic, const char *type,
                             size_t ntype, const char *encoding, const char *definition, size_t ndef, int schema,
                             int *index);
/* Channel index of a file id, -1 when unknown. */
int sooc_logs_find_channel(const sooc_logfile *lf, uint32_t file_id);
sooc_status sooc_logs_add_chunk(sooc_logfile *lf, const sooc_logs_chunk *c, int32_t *index);
sooc_status sooc_logs_add_entry(sooc_logfile *lf, int64_t t, uint64_t off, int32_t chunk, int32_t ch);
/* The uncompressed records of chunk c (cached). */
sooc_status sooc_logs_chunk_data(sooc_logfile *lf, int32_t c, const uint8_t **data, size_t *n);
const char *sooc_logs_comp_name(int comp);
/* "none"/"" -> NONE, "lz4", "bz2", "zstd"; -1 otherwise. */
int sooc_logs_comp_parse(const char *s, size_t n);

/* ---- per format ---- */
sooc_status sooc_logs_bag_open(sooc_logfile *lf);
/* The message record at off in a decompressed bag chunk. */
sooc_status sooc_logs_bag_message(sooc_logfile *lf, const uint8_t *chunk, size_t n, uint64_t off, uint64_t where,
                             const uint8_t **data, size_t *size);
sooc_status sooc_logs_mcap_open(sooc_logfile *lf);
sooc_status sooc_logs_mcap_message(sooc_logfile *lf, const uint8_t *rec, size_t n, uint64_t where, const uint8_t **data,
                              size_t *size);
sooc_status sooc_logs_mcap_verify(sooc_logfile *lf);

#endif
