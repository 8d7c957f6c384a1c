/* Private layout of sooc_cogmap (shared by the cogmap sources and tests only). */
#ifndef SOOC3D_COGMAP_IMPL_H
#define SOOC3D_COGMAP_IMPL_H

#include "sooc3d/cogmap.h"

#define SOOC_HEMPTY 0xffffffffu

/* open-addressing u64 -> u32 map; key and value share a slot (one cache line
 * per probe); val == SOOC_HEMPTY marks a free slot */
typedef struct sooc_hslot {
    uint64_t key;
    uint32_t val, pad;
} sooc_hslot;
typedef struct sooc_hmap {
    sooc_hslot *s;
    size_t cap, n;   /* cap is a power of two */
} sooc_hmap;

/* A cell member carries copies of what the centre-mode in-view test and the
 * top-K ranking need, so a query touches entries only for the K winners. */
typedef struct sooc_cell_member {
    double X, Z;     /* entry's floor position */
    uint64_t id;
    float pres;      /* presence logit */
    uint32_t idx;    /* dense entry index */
} sooc_cell_member;

typedef struct sooc_cell {
    int32_t ci, cj;
    uint32_t n, cap;
    sooc_cell_member *mem;
} sooc_cell;

typedef struct sooc_loc {
    uint32_t cell, slot;   /* entry's cell index and its position in the cell's member list */
} sooc_loc;

struct sooc_cogmap {
    int dim, ldim;
    double cell, inv_cell, block;
    uint64_t next_id;
    /* entries */
    sooc_cogmap_entry *ent;
    sooc_loc *loc;
    size_t n, ent_cap;
    sooc_hmap ids;         /* id -> dense index */
    /* grid */
    sooc_cell *cells;
    size_t n_cells, cap_cells;
    sooc_hmap cells_h;     /* pack(ci, cj) -> cell index */
    /* layout blocks */
    int32_t *blk_key;      /* 2 per block: bi, bj */
    float *blk_lat;        /* 2 * ldim per block: mu, logvar */
    size_t n_blk, cap_blk;
    sooc_hmap blocks_h;
    /* per-entry / per-block float payloads (finetuned decoders; payload.c) */
    struct sooc_cogmap_payloads *pl;
};

/* payload.c */
void sooc_cogmap_payloads_free(sooc_cogmap *m);

#endif
