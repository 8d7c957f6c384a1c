/* Helpers shared by the table tests: unique table names, a self-checking
 * record payload (every field derived from one counter), timing, fork helpers. */
#ifndef SOOC3D_TABLE_TEST_UTIL_H
#define SOOC3D_TABLE_TEST_UTIL_H

#include "sooc3d/table.h"

#include <stdio.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

static inline int64_t tt_mono_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000ll + ts.tv_nsec;
}

static inline void tt_sleep_ms(long ms) {
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    while (nanosleep(&ts, &ts) != 0) {
    }
}

/* "<tag>_<pid>": unique per test process, so parallel ctest runs never collide. */
static inline void tt_name(char *out, size_t cap, const char *tag) {
    snprintf(out, cap, "test_%s_%ld", tag, (long)getpid());
}

/* A record whose every field follows from (object_id, counter c). Floats stay
 * exact: the base is below 2^20. */
static inline void tt_make(sooc_table_record *r, uint64_t id, uint32_t c) {
    memset((void *)r, 0, sizeof *r);
    float v = (float)(c & 0xFFFFFu);
    r->object_id = id;
    r->flags = SOOC_TABLE_FLAG_VALID;
    r->obs_count = c;
    r->presence = v + 1;
    r->x = v + 2;
    r->z = v + 3;
    r->yaw = v + 4;
    for (int i = 0; i < 6; i++) r->cov_xzyaw[i] = v + 5 + (float)i;
    r->y = v + 11;
    for (int i = 0; i < 3; i++) r->extent[i] = v + 12 + (float)i;
    r->first_seen_ns = (int64_t)c * 3;
    r->last_seen_ns = (int64_t)c * 5 + (int64_t)id;
    r->latent_dim = SOOC_TABLE_LATENT_MAX;
    for (int i = 0; i < 32; i++) r->latent[i] = v + 20 + (float)i;
}

/* 1 if the record is exactly tt_make(id, obs_count) for its own id and count. */
static inline int tt_consistent(const sooc_table_record *r) {
    sooc_table_record e;
    tt_make(&e, r->object_id, r->obs_count);
    return memcmp((const char *)r + 8, (const char *)&e + 8, sizeof e - 8) == 0;
}

#endif
