/* Table basics in one process: ABI constants, names, mode 0640, writer/reader
 * round trip, remove and slot reuse, capacity, header info, heartbeat thread,
 * a second writer refused, clean close, incompatible re-creation. */
#include "check.h"
#include "table_test_util.h"

#include <errno.h>
#include <fcntl.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/stat.h>

static void test_abi(void) {
    CHECK(sooc_table_schema_hash() == SOOC_TABLE_SCHEMA_HASH);
    CHECK_MSG(sooc_table_schema_hash() == SOOC_TABLE_SCHEMA_HASH, "computed %016llx",
              (unsigned long long)sooc_table_schema_hash());
    CHECK(sizeof(sooc_table_record) == 256 && sizeof(sooc_table_header) == 4096);
    CHECK(strcmp(sooc_table_strerror(SOOC_TABLE_EBUSY), "table busy (seqlock retries exhausted)") == 0);
    CHECK(strcmp(sooc_table_strerror(12345), "unknown table error") == 0);
    /* REP-103: x_ros = -z, y_ros = -x, z_ros = y, yaw unchanged */
    sooc_table_record r;
    memset((void *)&r, 0, sizeof r);
    r.x = 1, r.z = 2, r.y = 0.5f, r.yaw = 0.3f;
    float c[6] = {1, 2, 3, 4, 5, 6}, cr[6], xr, yr, zr, yawr;
    memcpy(r.cov_xzyaw, c, sizeof c);
    sooc_table_pose_rep103(&r, &xr, &yr, &zr, &yawr, cr);
    CHECK(xr == -2 && yr == -1 && zr == 0.5f && yawr == 0.3f);
    CHECK(cr[0] == 4 && cr[1] == 2 && cr[2] == -5 && cr[3] == 1 && cr[4] == -3 && cr[5] == 6);
}

static void test_names(void) {
    CHECK(sooc_table_validate_name("map") == 0);
    CHECK(sooc_table_validate_name("lab-2.floor_A") == 0);
    const char *bad[] = {"", ".hidden", "a/b", "a b", "x\n", "..", "é", "a:b", NULL};
    for (int i = 0; bad[i]; i++)
        CHECK_MSG(sooc_table_validate_name(bad[i]) == SOOC_TABLE_EINVAL, "'%s'", bad[i]);
    CHECK(sooc_table_validate_name(NULL) == SOOC_TABLE_EINVAL);
    char longname[SOOC_TABLE_NAME_MAX + 2];
    memset(longname, 'a', sizeof longname - 1);
    longname[sizeof longname - 1] = 0;
    CHECK(sooc_table_validate_name(longname) == SOOC_TABLE_EINVAL);
    longname[SOOC_TABLE_NAME_MAX] = 0;
    CHECK(sooc_table_validate_name(longname) == 0);
    char shm[128];
    CHECK(sooc_table_shm_name("map", shm, sizeof shm) == 0 && strcmp(shm, "/sooc3d.v1.map") == 0);
    CHECK(sooc_table_shm_name("map", shm, 8) == SOOC_TABLE_ERANGE);
    sooc_table_writer *w = NULL;
    CHECK(sooc_table_create_writer("../etc", 4, 0, "map", &w) == SOOC_TABLE_EINVAL && !w);
    CHECK(sooc_table_create_writer("ok", 0, 0, "map", &w) == SOOC_TABLE_EINVAL);
    CHECK(sooc_table_create_writer("ok", 4, 01000, "map", &w) == SOOC_TABLE_EINVAL);
    CHECK(sooc_table_create_writer("ok", 4, 0, "a-frame-id-that-is-far-too-long-for-32", &w) ==
          SOOC_TABLE_EINVAL);
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader("no/such", &r) == SOOC_TABLE_EINVAL && !r);
    CHECK(sooc_table_open_reader("test_does_not_exist_x", &r) == SOOC_TABLE_ENOENT && !r);
}

static void test_roundtrip(void) {
    char name[64], path[128];
    tt_name(name, sizeof name, "basic");
    snprintf(path, sizeof path, "/dev/shm/sooc3d.v1.%s", name);
    mode_t old_umask = umask(077); /* fchmod must win over a strict umask */
    sooc_table_writer *w = NULL;
    int rc = sooc_table_create_writer(name, 8, 0, "map", &w);
    umask(old_umask);
    CHECK_MSG(rc == 0, "%s", sooc_table_strerror(rc));
    if (rc) return;
    struct stat st;
    CHECK(stat(path, &st) == 0);
    CHECK_MSG((st.st_mode & 0777) == 0640, "mode %o", (unsigned)(st.st_mode & 0777));
    CHECK(st.st_size == 4096 + 8 * 256);

    /* a second writer is refused while this one lives (flock, same process too) */
    sooc_table_writer *w2 = NULL;
    CHECK(sooc_table_create_writer(name, 8, 0, "map", &w2) == SOOC_TABLE_ELOCKED && !w2);

    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(name, &r) == 0);
    if (!r) return;
    CHECK(sooc_table_capacity(r) == 8 && sooc_table_epoch(r) == 0);
    sooc_table_liveness live;
    CHECK(sooc_table_writer_alive(r, &live) == 1 && live.lock_held && !live.exited);
    CHECK(live.writer_pid == getpid() && live.instance_id == sooc_table_writer_instance(w));

    sooc_table_record rec, out[8];
    uint32_t n = 99;
    uint64_t epoch = 99;
    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == 0 && n == 0 && epoch == 0);
    tt_make(&rec, 7, 1);
    CHECK(sooc_table_upsert(w, &rec) == SOOC_TABLE_ESTATE); /* outside a batch */
    CHECK(sooc_table_end_batch(w) == SOOC_TABLE_ESTATE);

    CHECK(sooc_table_begin_batch(w) == 0);
    CHECK(sooc_table_begin_batch(w) == SOOC_TABLE_ESTATE);
    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == SOOC_TABLE_EBUSY); /* batch open */
    for (uint64_t id = 10; id < 15; id++) {
        tt_make(&rec, id, (uint32_t)id * 3);
        CHECK(sooc_table_upsert(w, &rec) == 0);
    }
    tt_make(&rec, 0, 1);
    CHECK(sooc_table_upsert(w, &rec) == SOOC_TABLE_EINVAL); /* id 0 is "empty" */
    double T[16] = {1, 0, 0, 0.5, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    CHECK(sooc_table_set_meta(w, 32, 0xabcdef, 123456789, T) == 0);
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_writer_epoch(w) == 1 && sooc_table_writer_count(w) == 5);

    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == 0 && n == 5 && epoch == 1);
    for (uint32_t i = 0; i < n; i++) {
        CHECK(out[i].object_id == 10 + i && tt_consistent(&out[i]));
        CHECK(out[i].obs_count == (10 + i) * 3 && (out[i].seq & 1) == 0);
    }
    CHECK(sooc_table_snapshot(r, out, 3, &n, &epoch) == SOOC_TABLE_ERANGE && n == 5);
    CHECK(sooc_table_read_record(r, 2, &rec) == 0 && rec.object_id == 12 && tt_consistent(&rec));
    CHECK(sooc_table_read_record(r, 6, &rec) == 0 && rec.object_id == 0);
    CHECK(sooc_table_read_record(r, 8, &rec) == SOOC_TABLE_EINVAL);
    CHECK(sooc_table_find(r, 13, &rec) == 0 && rec.object_id == 13 && rec.obs_count == 39);
    CHECK(sooc_table_find(r, 99, &rec) == SOOC_TABLE_ENOENT);
    sooc_table_info info;
    CHECK(sooc_table_get_info(r, &info) == 0);
    CHECK(info.capacity == 8 && info.n_objects == 5 && info.high_water == 5 && info.epoch == 1);
    CHECK(info.latent_dim == 32 && info.latent_model_id == 0xabcdef && info.stamp_ns == 123456789);
    CHECK(info.T_src_map[3] == 0.5 && info.T_src_map[15] == 1.0);
    CHECK(strcmp(info.frame_id, "map") == 0 && (info.hflags & SOOC_TABLE_HFLAG_FLOOR_SET));

    /* update in place keeps the slot; remove keeps the record for >= 1 epoch */
    CHECK(sooc_table_begin_batch(w) == 0);
    tt_make(&rec, 12, 1000);
    CHECK(sooc_table_upsert(w, &rec) == 0);
    CHECK(sooc_table_remove(w, 11) == 0);
    CHECK(sooc_table_remove(w, 11) == SOOC_TABLE_ENOENT);
    CHECK(sooc_table_remove(w, 999) == SOOC_TABLE_ENOENT);
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_read_record(r, 2, &rec) == 0 && rec.object_id == 12 && rec.obs_count == 1000);
    CHECK(sooc_table_find(r, 11, &rec) == 0 && (rec.flags & SOOC_TABLE_FLAG_REMOVED) &&
          !(rec.flags & SOOC_TABLE_FLAG_VALID));
    CHECK(sooc_table_get_info(r, &info) == 0 && info.n_objects == 4);

    /* fill: slots 5..7 are fresh, then the removed slot 1 is reused, then full */
    CHECK(sooc_table_begin_batch(w) == 0);
    for (uint64_t id = 20; id < 23; id++) {
        tt_make(&rec, id, 5);
        CHECK(sooc_table_upsert(w, &rec) == 0);
    }
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_find(r, 11, &rec) == 0); /* still visible as removed */
    CHECK(sooc_table_begin_batch(w) == 0);
    tt_make(&rec, 30, 5);
    CHECK(sooc_table_upsert(w, &rec) == 0);
    tt_make(&rec, 31, 5);
    CHECK(sooc_table_upsert(w, &rec) == SOOC_TABLE_EFULL);
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_read_record(r, 1, &rec) == 0 && rec.object_id == 30);
    CHECK(sooc_table_find(r, 11, &rec) == SOOC_TABLE_ENOENT);
    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == 0 && n == 8 && epoch == 4);

    /* clear removes all; they stay visible as REMOVED */
    CHECK(sooc_table_begin_batch(w) == 0);
    CHECK(sooc_table_clear(w) == 0);
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_writer_count(w) == 0);
    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == 0 && n == 8);
    for (uint32_t i = 0; i < n; i++) CHECK(out[i].flags & SOOC_TABLE_FLAG_REMOVED);

    /* heartbeat thread */
    CHECK(sooc_table_start_heartbeat(w, 50) == 0);
    CHECK(sooc_table_start_heartbeat(w, 50) == SOOC_TABLE_ESTATE);
    tt_sleep_ms(120);
    CHECK(sooc_table_writer_alive(r, &live) == 1);
    {   /* the thread beats: the header's heartbeat moves (waited for up to 10 s: no bound on scheduling) */
        sooc_table_info i0, i1;
        CHECK(sooc_table_get_info(r, &i0) == 0);
        int moved = 0;
        for (int k = 0; k < 1000 && !moved; k++) {
            tt_sleep_ms(10);
            moved = sooc_table_get_info(r, &i1) == 0 && i1.heartbeat_mono_ns > i0.heartbeat_mono_ns;
        }
        CHECK_MSG(moved, "the heartbeat did not move in 10 s");
    }

    /* clean close: WRITER_EXITED, lock released, the object persists */
    CHECK(sooc_table_close_writer(w, 0) == 0);
    CHECK(sooc_table_writer_alive(r, &live) == 0 && live.exited && !live.lock_held);
    CHECK(stat(path, &st) == 0);
    sooc_table_close_reader(r);

    /* reopen with the same layout adopts the records; another capacity recreates */
    CHECK(sooc_table_create_writer(name, 8, 0, "map", &w) == 0);
    CHECK(sooc_table_open_reader(name, &r) == 0);
    CHECK(sooc_table_snapshot(r, out, 8, &n, &epoch) == 0 && n == 8 && epoch == 6);
    CHECK(sooc_table_writer_alive(r, &live) == 1 && !live.exited);
    CHECK(sooc_table_close_writer(w, 0) == 0);
    CHECK(sooc_table_create_writer(name, 16, 0, "map", &w) == 0);
    CHECK(sooc_table_writer_alive(r, &live) == 0); /* old object orphaned: lock free */
    sooc_table_close_reader(r);
    CHECK(sooc_table_open_reader(name, &r) == 0);
    CHECK(sooc_table_capacity(r) == 16 && sooc_table_epoch(r) == 0);
    CHECK(sooc_table_close_writer(w, 1) == 0);
    sooc_table_close_reader(r);
    CHECK(stat(path, &st) != 0 && errno == ENOENT);
}

/* Readers reject a table whose header does not match the ABI. */
static void test_version_check(void) {
    char name[64], shm[128];
    tt_name(name, sizeof name, "ver");
    sooc_table_writer *w = NULL;
    CHECK(sooc_table_create_writer(name, 4, 0, "map", &w) == 0);
    CHECK(sooc_table_close_writer(w, 0) == 0);
    sooc_table_shm_name(name, shm, sizeof shm);
    int fd = shm_open(shm, O_RDWR, 0);
    CHECK(fd >= 0);
    sooc_table_header *h = mmap(NULL, 4096, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
    sooc_table_reader *r = NULL;
    h->schema_hash ^= 1;
    CHECK(sooc_table_open_reader(name, &r) == SOOC_TABLE_EVERSION);
    h->schema_hash ^= 1;
    h->abi_major = 2;
    CHECK(sooc_table_open_reader(name, &r) == SOOC_TABLE_EVERSION);
    h->abi_major = 1;
    atomic_store(&h->magic, 0);
    CHECK(sooc_table_open_reader(name, &r) == SOOC_TABLE_ENOTREADY);
    atomic_store(&h->magic, SOOC_TABLE_MAGIC);
    CHECK(sooc_table_open_reader(name, &r) == 0);
    sooc_table_close_reader(r);
    munmap(h, 4096);
    close(fd);
    shm_unlink(shm);
}

/* The node's pattern: clear and re-insert everything every batch. Removed
 * slots must still be reclaimed afterwards (no slot leak in the queue). */
static void test_clear_reinsert(void) {
    char name[64];
    tt_name(name, sizeof name, "reins");
    sooc_table_writer *w = NULL;
    CHECK(sooc_table_create_writer(name, 4, 0, "map", &w) == 0);
    if (!w) return;
    sooc_table_record rec;
    for (int b = 0; b < 50; b++) {
        CHECK(sooc_table_begin_batch(w) == 0);
        CHECK(sooc_table_clear(w) == 0);
        for (uint64_t id = 1; id <= 4; id++) {
            tt_make(&rec, id, (uint32_t)b);
            CHECK(sooc_table_upsert(w, &rec) == 0);
        }
        CHECK(sooc_table_end_batch(w) == 0);
    }
    CHECK(sooc_table_writer_count(w) == 4);
    CHECK(sooc_table_begin_batch(w) == 0);
    CHECK(sooc_table_remove(w, 4) == 0);
    CHECK(sooc_table_end_batch(w) == 0);
    for (int b = 0; b < 2; b++) {
        CHECK(sooc_table_begin_batch(w) == 0);
        CHECK(sooc_table_end_batch(w) == 0);
    }
    CHECK(sooc_table_begin_batch(w) == 0);
    tt_make(&rec, 5, 1);
    CHECK(sooc_table_upsert(w, &rec) == 0);
    tt_make(&rec, 6, 1);
    CHECK(sooc_table_upsert(w, &rec) == SOOC_TABLE_EFULL);
    CHECK(sooc_table_end_batch(w) == 0);
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(name, &r) == 0);
    sooc_table_record out[4];
    uint32_t n = 0;
    CHECK(r && sooc_table_snapshot(r, out, 4, &n, NULL) == 0 && n == 4);
    CHECK(sooc_table_find(r, 4, &rec) == SOOC_TABLE_ENOENT && sooc_table_find(r, 5, &rec) == 0);
    sooc_table_close_reader(r);
    CHECK(sooc_table_close_writer(w, 1) == 0);
}

int main(void) {
    test_abi();
    test_clear_reinsert();
    test_names();
    test_roundtrip();
    test_version_check();
    return check_report("test_table_basic");
}
