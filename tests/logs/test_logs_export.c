/* sooc3d map export --mcap (Foxglove): a stored map of 250 objects (one with
 * a computed box) and a world frame, exported through the binary (SOOC_BIN)
 * and read back with the log reader: the two Foxglove channels, JSON that
 * python3 parses (when python3 is there), SceneUpdates in first-seen order
 * grouped to at most 200 messages, the last holding every object with its
 * cube, label and metadata, and the frame transforms map -> world -> source. */
#include "logs_util.h"
#include "sooc3d/cogmap.h"

#include <math.h>

#define N_OBJ 250

static int count(const char *s, size_t n, const char *needle) {
    int k = 0;
    size_t m = strlen(needle);
    for (size_t i = 0; i + m <= n; i++)
        if (!memcmp(s + i, needle, m)) k++;
    return k;
}

int main(void) {
    const char *bin = getenv("SOOC_BIN"), *py = getenv("SOOC_PYTHON3");
    if (!bin || !sooc_file_exists(bin)) {
        printf("test_logs_export: SKIP: no sooc3d binary (SOOC_BIN)\n");
        return SOOC_TEST_SKIP;
    }
    char *tmp = lu_tmpdir("logs_export");
    char db[600], out[600], cmd[2048];
    snprintf(db, sizeof db, "%s/map.sqlite", tmp);
    snprintf(out, sizeof out, "%s/map.mcap", tmp);
    sooc_cogmap_params mp;
    sooc_cogmap_params_default(&mp);
    mp.dim = 4;
    mp.layout_dim = 2;
    sooc_cogmap *m = NULL;
    CHECK_OK(sooc_cogmap_create(&m, &mp));
    for (int i = 0; i < N_OBJ && m; i++) {
        sooc_cogmap_entry e;
        memset(&e, 0, sizeof e);
        e.X = 0.1 * (i % 20);
        e.Z = 0.1 * (i / 20);
        e.Theta = 0.01 * i;
        e.rho_t = -4;
        e.rho_theta = -2;
        e.pres_logit = 3;
        e.dim = 4;
        e.obs_count = 1 + i % 3;
        e.first_seen_ns = 1000000000LL + 10000000LL * (N_OBJ - i);   /* seen in the reverse of id order */
        e.last_seen_ns = e.first_seen_ns + 5000000000LL;
        CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
    }
    sooc_mapstore_params sp;
    sooc_mapstore_params_default(&sp);
    sp.dim = 4;
    sp.layout_dim = 2;
    sp.model_id = "export-test";
    sooc_mapstore *s = NULL;
    CHECK_OK(sooc_mapstore_open(&s, db, &sp));
    if (s) {
        CHECK_OK(sooc_mapstore_save_map(s, m));
        const float ext[3] = {0.1f, 0.2f, 0.3f};
        sooc_map_geometry g;
        memset(&g, 0, sizeof g);
        g.flags = SOOC_GEOM_TIGHT;
        g.centre[1] = 0.1f;
        CHECK_OK(sooc_mapstore_geom_put(s, 8, ext, &g));
        sooc_map_frame fr;
        memset(&fr, 0, sizeof fr);
        double T[16] = {1, 0, 0, 0.5, 0, 0, 1, 0, 0, -1, 0, 1.2, 0, 0, 0, 1};   /* z up -> y up, 1.2 m */
        memcpy(fr.T_world_src, T, sizeof T);
        fr.up_src[2] = 1;
        fr.up_source = -1;
        CHECK_OK(sooc_mapstore_frame_put(s, &fr));
        sooc_mapstore_close(s);
    }
    sooc_cogmap_destroy(m);

    snprintf(cmd, sizeof cmd, "'%s' map export --db '%s' --mcap '%s'", bin, db, out);
    CHECK_MSG(system(cmd) == 0, "%s failed", cmd);
    snprintf(cmd, sizeof cmd, "'%s' map export --db '%s' --mcap '%s' --box 0 0 1 1 2>/dev/null", bin, db, out);
    CHECK_MSG(system(cmd) != 0, "--mcap with --box should be refused");

    sooc_logfile *lf = NULL;
    CHECK_OK(sooc_logfile_open(&lf, out));
    if (lf) {
        CHECK_OK(sooc_logfile_verify(lf));
        int obj = sooc_logfile_find(lf, "/sooc3d/objects"), frm = sooc_logfile_find(lf, "/sooc3d/frames");
        CHECK(obj >= 0 && frm >= 0);
        const sooc_logfile_channel *co = sooc_logfile_channel_get(lf, obj), *cf = sooc_logfile_channel_get(lf, frm);
        CHECK(co && !strcmp(co->type, "foxglove.SceneUpdate") && !strcmp(co->encoding, "json"));
        CHECK(cf && !strcmp(cf->type, "foxglove.FrameTransform") && cf->count == 2);
        CHECK(co && strstr(co->definition, "\"foxglove.CubePrimitive\"") != NULL);
        CHECK_MSG(co && co->count == 125, "%lld SceneUpdates, expected 125 (250 objects, 2 per message)",
                  co ? (long long)co->count : -1LL);
        FILE *js = NULL;
        char jpath[700];
        snprintf(jpath, sizeof jpath, "%s/messages.jsonl", tmp);
        js = fopen(jpath, "w");
        int64_t prev_t = -1, ordered = 1, last_entities = -1;
        for (int64_t k = 0; k < sooc_logfile_count(lf); k++) {
            sooc_logfile_msg msg;
            CHECK_OK(sooc_logfile_read(lf, k, &msg));
            const char *t = (const char *)msg.data;
            if (js) {
                fwrite(t, 1, msg.size, js);
                fputc('\n', js);
            }
            if (msg.channel != obj) {
                CHECK(count(t, msg.size, "\"parent_frame_id\"") == 1);
                continue;
            }
            if (msg.t_ns < prev_t) ordered = 0;
            prev_t = msg.t_ns;
            last_entities = count(t, msg.size, "\"frame_id\": \"world\"");
            if (k == sooc_logfile_count(lf) - 1) {
                CHECK(count(t, msg.size, "\"cubes\"") == N_OBJ && count(t, msg.size, "\"texts\"") == N_OBJ);
                CHECK(count(t, msg.size, "{\"key\": \"presence\"") == N_OBJ);
                CHECK(strstr(t, "\"id\": \"object 1\"") && strstr(t, "\"id\": \"object 250\""));
                /* object 8's box: 0.1 x 0.2 (its tight height) x 0.3, centred 0.1 m up */
                CHECK_MSG(strstr(t, "\"size\": {\"x\": 0.1000, \"y\": 0.2000, \"z\": 0.3000}") != NULL, "object 8's box");
            }
        }
        if (js) fclose(js);
        CHECK(ordered);
        CHECK_MSG(last_entities == N_OBJ, "the last SceneUpdate holds %lld objects, expected %d", (long long)last_entities,
                  N_OBJ);
        sooc_logfile_close(lf);
        if (py && *py && sooc_file_exists(py)) {
            snprintf(cmd, sizeof cmd,
                     "'%s' -c \"import json,sys; n=[len(json.loads(l).get('entities',[])) for l in open('%s')]; "
                     "sys.exit(0 if n[-1]==%d else 1)\"",
                     py, jpath, N_OBJ);
            CHECK_MSG(system(cmd) == 0, "python3 json could not read the messages (%s)", jpath);
        } else {
            printf("  (python3 not found: the JSON is checked by its fields only)\n");
        }
        printf("  %d objects: 125 SceneUpdates in first-seen order, the last with every object; 2 FrameTransforms\n",
               N_OBJ);
    }
    snprintf(cmd, sizeof cmd, "rm -rf '%s'", tmp);
    if (!g_check_fail && system(cmd) != 0) printf("could not remove %s\n", tmp);
    return check_report("test_logs_export");
}
