/* Private layout of sooc_cogmap (shared by the cogmap sources and tests only). */
#ifndef SOOC3D_COGMAP_IMPL_H
#define SOOC3D_COGMAP_IMPL_H

#include "sooc3d/cogmap.h"

#define SOOC_HEMPTY 0xffffffffu

/* open-addressing u64 -> u32 map; vals[i] == SOOC_HEMPTY marks a free slot */
typedef struct sooc_hmap {
    uint64_t *keys;
    uint32_t *vals;
    size_t cap, n;   /* cap is a power of two */
} sooc_hmap;

typedef struct sooc_cell_member {
    double X, Z;     /* copy of the entry's floor position (pre-filter without touching entries) */
    uint32_t idx;    /* dense entry index */
    uint32_t pad;
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
};

#endif
