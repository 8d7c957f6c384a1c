/* An out-of-tree C11 planner (test_table_install): built against an installed
 * sooc3d_table through pkg-config and through find_package, it reads the live
 * table written by table_test_writer and checks what it holds.
 *   planner_c11 <name>   -> exit 0 if objects 11, 12, 13 are there and the writer is alive */
#include <sooc3d/table.h>

#include <stdio.h>
#include <string.h>

int main(int argc, char **argv) {
    if (argc != 2) return 2;
    sooc_table_reader *r = NULL;
    int rc = sooc_table_open_reader(argv[1], &r);
    if (rc != 0) {
        fprintf(stderr, "C11 planner: open '%s': %s\n", argv[1], sooc_table_strerror(rc));
        return 1;
    }
    sooc_table_record recs[16];
    uint32_t n = 0;
    uint64_t epoch = 0;
    sooc_table_info info;
    sooc_table_liveness live;
    int bad = 0;
    rc = sooc_table_snapshot(r, recs, 16, &n, &epoch);
    if (rc == 0) rc = sooc_table_get_info(r, &info);
    if (rc != 0) {
        fprintf(stderr, "C11 planner: %s\n", sooc_table_strerror(rc));
        bad = 1;
    } else {
        if (n != 3 || strcmp(info.frame_id, "map") != 0 || info.latent_model_id != 0x5eedull) bad = 1;
        for (uint32_t i = 0; i < n && !bad; i++) {
            sooc_table_record c = recs[i];
            if (c.object_id != 11 + i || c.x != 0.5f * (float)c.object_id || c.z != -1.0f ||
                !(c.flags & SOOC_TABLE_FLAG_VALID))
                bad = 1;
        }
        if (sooc_table_writer_alive(r, &live) != 1) bad = 1;
        printf("C11 planner: epoch %llu, %u objects (first id %llu), frame %s, writer pid %lld %s\n",
               (unsigned long long)epoch, n, n ? (unsigned long long)recs[0].object_id : 0ull,
               info.frame_id, (long long)info.writer_pid, bad ? "MISMATCH" : "ok");
    }
    sooc_table_close_reader(r);
    return bad;
}
