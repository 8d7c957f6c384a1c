/* The geometric baseline through `sooc3d eval --baseline geometric` ($SOOC_BIN):
 *  - on generated tabletop scenes (known objects): the 'geometric' rows of
 *    the input and query views are in the JSON and the Markdown, their mIoU
 *    is well above a map that explains nothing (> 0.6 on the query views;
 *    objects on the generator's tables stand apart) and their matched
 *    objects lie within 5 cm; the same run twice gives the same figures (it
 *    is deterministic); a model named 'geometric' is refused;
 *  - on a recorded sequence (YCB-Video 0000 from ../shared/real, skipped when
 *    absent): a 'geometric' cell with obj_ids [8, 14, 21]. */
#include "../cli_util.h"
#include "sooc3d/model.h"

#include <string.h>

static double json_num_after(const char *js, const char *anchor, const char *key) {
    const char *a = js ? strstr(js, anchor) : NULL;
    const char *k = a ? strstr(a, key) : NULL;
    return k ? atof(k + strlen(key)) : NAN;
}

int main(void) {
    const char *bin = getenv("SOOC_BIN"), *real = getenv("SOOC_SHARED_REAL");
    if (!bin) {
        printf("test_eval_geometric: SOOC_BIN not set\n");
        return 1;
    }
    char tmp[] = "/tmp/sooc_geo_XXXXXX", cmd[4096], p[1024], model[600];
    if (!mkdtemp(tmp)) return 1;
    /* an untrained 64x64 model: its rows are not under test, it sets the frames' size */
    snprintf(model, sizeof model, "%s/m64.bin", tmp);
    {
        sooc_model_config c;
        sooc_model_config_default(&c);
        c.K = 3, c.d_what = 8, c.d_layout = 4, c.L = 1;
        c.ray_w = c.ray_h = 16;
        c.dec_width = 16, c.dec_color_width = 8;
        c.ref_ch[0] = c.ref_ch[1] = c.ref_ch[2] = c.ref_ch[3] = 8;
        c.ref_fc = 16, c.ref_hidden = 16;
        c.unit_m = 0.285714f;
        sooc_model *m = NULL;
        CHECK_OK(sooc_model_create(&m, &c, 3));
        if (m) CHECK_OK(sooc_model_save(m, model, NULL, 0));
        sooc_model_destroy(m);
    }
    snprintf(cmd, sizeof cmd, "%s gen --preset tabletop --no-sheet --scale s --scenes 2 --seed 77 --out %s/gen > /dev/null",
             bin, tmp);
    CHECK(tc_run(cmd) == 0);
    char *js[2] = {NULL, NULL};
    for (int r = 0; r < 2; r++) {
        snprintf(cmd, sizeof cmd,
                 "%s eval --model %s --name m64 --data %s/gen --baseline geometric --mesh-res 0 --samples 16,0 "
                 "--json %s/g%d.json --md %s/g%d.md --quiet > /dev/null",
                 bin, model, tmp, tmp, r, tmp, r);
        CHECK(tc_run(cmd) == 0);
        snprintf(p, sizeof p, "%s/g%d.json", tmp, r);
        js[r] = tc_slurp(p);
    }
    const char *q = "\"model\": \"geometric\", \"scale\": \"s\", \"view\": \"Q\"";
    const char *in = "\"model\": \"geometric\", \"scale\": \"s\", \"view\": \"I\"";
    double miou_q = json_num_after(js[0], q, "\"miou\": {\"mean\": ");
    double miou_i = json_num_after(js[0], in, "\"miou\": {\"mean\": ");
    double l2 = json_num_after(js[0], q, "\"l2\": {\"mean\": ");
    printf("geometric on 2 generated tabletop scenes: mIoU input %.3f query %.3f, L2 %.3f m\n", miou_i, miou_q, l2);
    CHECK_MSG(miou_q > 0.6 && miou_i > 0.6, "mIoU input %.3f query %.3f", miou_i, miou_q);
    CHECK_MSG(l2 < 0.05, "L2 %.3f m", l2);
    CHECK_MSG(js[0] && js[1] && miou_q == json_num_after(js[1], q, "\"miou\": {\"mean\": "), "not deterministic");
    snprintf(p, sizeof p, "%s/g0.md", tmp);
    char *md = tc_slurp(p);
    CHECK_MSG(md && strstr(md, "geometric"), "the Markdown table has no geometric row");
    sooc_free(md);
    sooc_free(js[0]);
    sooc_free(js[1]);
    /* the baseline's row name is taken */
    snprintf(cmd, sizeof cmd, "%s eval --model %s --name geometric --data %s/gen --baseline geometric --json %s/x.json "
             "--quiet > /dev/null 2>&1", bin, model, tmp, tmp);
    CHECK(tc_run(cmd) != 0);
    snprintf(cmd, sizeof cmd, "%s eval --model %s --data %s/gen --baseline plane --json %s/x.json > /dev/null 2>&1", bin,
             model, tmp, tmp);
    CHECK(tc_run(cmd) == 2);

    /* a recorded sequence with ground-truth labels */
    char ycb[1024];
    snprintf(ycb, sizeof ycb, "%s/ycb_video/data/0000", real ? real : "../shared/real");
    int skipped = 0;
    if (!sooc_dir_exists(ycb)) {
        printf("test_eval_geometric: SKIP the YCB-Video part: %s is absent\n", ycb);
        skipped = 1;
    } else {
        snprintf(cmd, sizeof cmd, "%s eval --model %s --name m64 --data %s --baseline geometric --no-second-pass "
                 "--no-own-surface --samples 16,0 --json %s/ycb.json --quiet > /dev/null 2>&1", bin, model, ycb, tmp);
        CHECK(tc_run(cmd) == 0);
        snprintf(p, sizeof p, "%s/ycb.json", tmp);
        char *y = tc_slurp(p);
        const char *g = y ? strstr(y, "\"model\": \"geometric\"") : NULL;
        CHECK_MSG(g && strstr(g, "\"obj_ids\": [8, 14, 21]") && strstr(g, "\"obj_iou\": ["),
                  "ycb.json: %s", y ? y : "(missing)");
        sooc_free(y);
    }
    snprintf(cmd, sizeof cmd, "rm -rf %s", tmp);
    if (system(cmd)) {}
    printf("test_eval_geometric: %d checks, %d failed\n", g_check_n, g_check_fail);
    (void)skipped;   /* the generated part ran: a pass, with the SKIP line above */
    return g_check_fail ? 1 : 0;
}
