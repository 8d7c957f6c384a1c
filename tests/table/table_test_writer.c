/* table_test_writer: a live table for tests outside the tree (the install test).
 *
 *   table_test_writer <name> <timeout_s>
 *
 * Creates table <name> (capacity 16, frame "map") holding objects 11, 12 and
 * 13 (x = id / 2, z = -1, yaw = 0.25, presence 0.75, VALID), runs the 20 Hz
 * heartbeat, prints "ready" on stdout, then waits until stdin reaches EOF or
 * timeout_s seconds pass, and closes the table with unlink. Exit 0, or 1 with
 * a message on stderr. */
#include "sooc3d/table.h"

#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: table_test_writer <name> <timeout_s>\n");
        return 2;
    }
    int timeout_ms = atoi(argv[2]) * 1000;
    sooc_table_writer *w = NULL;
    int rc = sooc_table_create_writer(argv[1], 16, 0, "map", &w);
    if (rc != 0) {
        fprintf(stderr, "table_test_writer: create '%s': %s\n", argv[1], sooc_table_strerror(rc));
        return 1;
    }
    rc = sooc_table_start_heartbeat(w, 20);
    if (rc == 0) rc = sooc_table_begin_batch(w);
    for (uint64_t id = 11; id <= 13 && rc == 0; id++) {
        sooc_table_record rec;
        memset((void *)&rec, 0, sizeof rec);
        rec.object_id = id;
        rec.flags = SOOC_TABLE_FLAG_VALID;
        rec.obs_count = 2;
        rec.presence = 0.75f;
        rec.x = 0.5f * (float)id;
        rec.z = -1.0f;
        rec.yaw = 0.25f;
        rec.extent[0] = rec.extent[1] = rec.extent[2] = 0.5f;
        rc = sooc_table_upsert(w, &rec);
    }
    if (rc == 0) rc = sooc_table_set_meta(w, 0, 0x5eedull, 42, NULL);
    if (rc == 0) rc = sooc_table_end_batch(w);
    if (rc != 0) {
        fprintf(stderr, "table_test_writer: %s\n", sooc_table_strerror(rc));
        sooc_table_close_writer(w, 1);
        return 1;
    }
    printf("ready\n");
    fflush(stdout);
    struct pollfd p = {0, POLLIN, 0};
    char buf[64];
    while (poll(&p, 1, timeout_ms) > 0 && read(0, buf, sizeof buf) > 0) {
    }
    sooc_table_close_writer(w, 1);
    return 0;
}
