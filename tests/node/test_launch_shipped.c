/* Every shipped launch file that names recorded data runs as shipped on it
 * ($SOOC_BIN, from the repository root) and creates its object table:
 * launch/7scenes_replay.yaml, 7scenes_odometry.yaml, labelfusion_replay.yaml
 * and tabletop_geometric.yaml on ../shared/real (skipped when absent), and
 * replay_demo.yaml on the scene scripts/demo.sh writes (generated here when
 * absent). Only the map database goes to a temporary folder (the shipped
 * files write under out/) and the runs stop after a few keyframes; the shm
 * name, the model and every other key are the file's. After each run the
 * table is opened by the file's name, holds the run's objects and says the
 * writer finished. The launch files for devices (OpenNI2, libfreenect,
 * V4L2, a socket pose) need hardware: test_node_units parses them. */
#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/table.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* the value of `name:` in the launch file's shm section */
static int shm_name(const char *launch, char *out, size_t cap) {
    FILE *f = fopen(launch, "r");
    if (!f) return 0;
    char line[512];
    int in_shm = 0, ok = 0;
    while (!ok && fgets(line, sizeof line, f)) {
        if (!strncmp(line, "shm:", 4)) in_shm = 1;
        else if (line[0] != ' ' && line[0] != '#' && line[0] != '\n') in_shm = 0;
        const char *p = in_shm ? strstr(line, "name:") : NULL;
        if (p) {
            p += 5;
            while (*p == ' ') p++;
            size_t n = strcspn(p, ",} \n#");
            if (n && n < cap) memcpy(out, p, n), out[n] = 0, ok = 1;
        }
    }
    fclose(f);
    return ok;
}

int main(void) {
    const char *bin = getenv("SOOC_BIN"), *real = getenv("SOOC_SHARED_REAL");
    if (!bin) {
        printf("test_launch_shipped: SOOC_BIN not set\n");
        return 1;
    }
    if (!real) real = "../shared/real";
    char dir[] = "/tmp/sooc_launch_XXXXXX", cmd[4096], name[128], data[1024];
    if (!mkdtemp(dir)) return 1;
    static const struct { const char *launch, *data; int keyframes; } runs[] = {
        {"launch/7scenes_replay.yaml", "7scenes_redkitchen", 4},
        {"launch/7scenes_odometry.yaml", "7scenes_redkitchen", 4},
        {"launch/labelfusion_replay.yaml", "label_fusion/data/labels", 4},
        {"launch/tabletop_geometric.yaml", "ycb_video/data/0000", 10},
        {"launch/replay_demo.yaml", NULL, 6},
    };
    int ran = 0, skipped = 0;
    for (size_t i = 0; i < sizeof runs / sizeof *runs; i++) {
        int made_demo = 0;
        if (runs[i].data) {
            snprintf(data, sizeof data, "%s/%s", real, runs[i].data);
            if (!sooc_dir_exists(data)) {
                printf("test_launch_shipped: SKIP %s: %s is absent (the real recordings, ../shared/real)\n",
                       runs[i].launch, data);
                skipped++;
                continue;
            }
        } else if (!sooc_dir_exists("out/demo/scene")) {
            /* the scene scripts/demo.sh writes for the demo's launch file */
            snprintf(cmd, sizeof cmd, "'%s' gen --no-sheet --scale s --scenes 1 --seed 1 --out %s/demo > /dev/null && "
                     "mkdir -p out/demo && ln -sfn %s/demo/scene_0000 out/demo/scene", bin, dir, dir);
            CHECK(system(cmd) == 0);
            made_demo = 1;
        }
        CHECK_MSG(shm_name(runs[i].launch, name, sizeof name), "%s: no shm.name", runs[i].launch);
        snprintf(cmd, sizeof cmd,
                 "'%s' node %s --set map.db=%s/%zu.sqlite --max-keyframes %d --quiet > %s/log%zu.txt 2>&1", bin,
                 runs[i].launch, dir, i, runs[i].keyframes, dir, i);
        int rc = system(cmd);
        CHECK_MSG(rc == 0, "%s: exit %d (%s/log%zu.txt)", runs[i].launch, rc, dir, i);
        if (rc) {
            snprintf(cmd, sizeof cmd, "tail -5 %s/log%zu.txt", dir, i);
            if (system(cmd)) {}
        }
        sooc_table_reader *rd = NULL;
        CHECK_MSG(sooc_table_open_reader(name, &rd) == 0, "%s: no table '%s'", runs[i].launch, name);
        if (rd) {
            sooc_table_info info;
            CHECK(sooc_table_get_info(rd, &info) == 0);
            printf("%s: table '%s', %llu objects after %d keyframes, epoch %llu\n", runs[i].launch, name,
                   (unsigned long long)info.n_objects, runs[i].keyframes, (unsigned long long)info.epoch);
            CHECK_MSG(info.epoch >= 1, "%s: the table was never published", runs[i].launch);
            sooc_table_close_reader(rd);
        }
        char shm[160];
        if (!sooc_table_shm_name(name, shm, sizeof shm)) {
            snprintf(cmd, sizeof cmd, "rm -f /dev/shm%s", shm);
            if (system(cmd)) {}
        }
        if (made_demo && system("rm -f out/demo/scene")) {}
        ran++;
    }
    snprintf(cmd, sizeof cmd, "rm -rf %s", dir);
    if (system(cmd)) {}
    printf("test_launch_shipped: %d launch files run, %d skipped; %d checks, %d failed\n", ran, skipped, g_check_n,
           g_check_fail);
    return g_check_fail ? 1 : 0;
}
