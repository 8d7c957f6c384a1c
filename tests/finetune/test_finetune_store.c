/* Finetuned decoders in the map: cogmap payloads, the map
 * database's schema 2 and its migration, and the model's field drawing them.
 *  1. A version-1 map written by the node before schema 2
 *     (tests/finetune/map_v1_unity_m.sqlite: 10 entries, 24 keyframes):
 *     read-only it opens as version 1 with no decoders (storing one is
 *     refused); read-write it is migrated to version 2 with nothing lost.
 *  2. ft_put / load_map / save_map round trips, one transaction each; deleting
 *     an entry deletes its decoder; a corrupt blob is refused naming the file.
 *  3. sooc_model_field_create: a payload with the model's weights and the
 *     entry's z renders exactly as the base model, a changed copy renders
 *     differently, a payload of the wrong shape is ignored. */
#include "check.h"
#include "model/dec_own.h"
#include "model/synth.h"
#include "sooc3d/cogmap.h"
#include "sooc3d/render.h"

#include <sqlite3.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

static const char *k_fixture = "tests/finetune/map_v1_unity_m.sqlite";

static sooc_status copy_file(const char *src, const char *dst) {
    void *buf = NULL;
    size_t n = 0;
    sooc_status st = sooc_file_read_all(src, (size_t)1 << 26, &buf, &n);
    if (st) return st;
    st = sooc_file_write_atomic(dst, buf, n);
    sooc_free(buf);
    return st;
}

static sooc_cogmap *new_map(int dim, int ldim) {
    sooc_cogmap_params cp;
    sooc_cogmap_params_default(&cp);
    cp.dim = dim, cp.layout_dim = ldim;
    sooc_cogmap *m = NULL;
    sooc_cogmap_create(&m, &cp);
    return m;
}

static void test_store(void) {
    char path[256];
    snprintf(path, sizeof path, "/tmp/sooc_test_ft_store_%d.sqlite", (int)getpid());
    CHECK_OK(copy_file(k_fixture, path));
    sooc_mapstore *s = NULL;
    sooc_mapstore_info info;
    sooc_mapstore_params p;
    sooc_mapstore_params_default(&p);
    p.create = 0, p.readonly = 1;
    /* 1a. read-only: version 1, everything there, no decoders */
    CHECK_OK(sooc_mapstore_open(&s, path, &p));
    if (!s) return;
    CHECK_OK(sooc_mapstore_info_get(s, &info));
    CHECK(info.schema_version == 1 && info.n_entries == 10 && info.n_keyframes == 24 && info.dim == 32);
    sooc_cogmap *map = new_map(32, 16);
    CHECK_OK(sooc_mapstore_load_map(s, map));
    CHECK(sooc_cogmap_count(map) == 10 && sooc_cogmap_payload_count(map) == 0);
    uint64_t no = 9, nb = 9;
    CHECK_OK(sooc_mapstore_ft_count(s, &no, &nb));
    CHECK(no == 0 && nb == 0);
    float v[100];
    for (int i = 0; i < 100; i++) v[i] = 0.01f * (float)i - 0.3f;
    sooc_cogmap_entry ent[10];
    size_t ne = 0;
    CHECK_OK(sooc_cogmap_entries(map, ent, 10, &ne));
    CHECK(sooc_mapstore_ft_put(s, 0, ent[0].id, 0, 0, v, 100, 5, 1.0) == SOOC_EUNSUPPORTED);
    sooc_clearerr();
    size_t nkv = 0;
    CHECK_OK(sooc_mapstore_keyframe_views(s, NULL, 0, &nkv));
    CHECK(nkv == 24);
    sooc_mapstore_close(s);
    /* 1b. read-write: migrated to version 2, nothing lost */
    p.readonly = 0;
    CHECK_OK(sooc_mapstore_open(&s, path, &p));
    if (!s) return;
    CHECK_OK(sooc_mapstore_info_get(s, &info));
    CHECK_MSG(info.schema_version == SOOC_MAPSTORE_SCHEMA_VERSION && info.schema_version >= 2 && info.n_entries == 10 && info.n_keyframes == 24, "v %d e %llu k %llu", info.schema_version, (unsigned long long)info.n_entries, (unsigned long long)info.n_keyframes);
    char b[64];
    CHECK_OK(sooc_mapstore_meta_get(s, "world_frame", b, sizeof b));
    CHECK_OK(sooc_mapstore_meta_get(s, "extent", b, sizeof b));
    /* 2. decoders: entry, block; bad ones refused */
    CHECK_OK(sooc_mapstore_ft_put(s, 0, ent[0].id, 0, 0, v, 100, 120, -3.25));
    CHECK_OK(sooc_mapstore_ft_put(s, 1, 0, -1, 2, v + 10, 90, 120, NAN));
    CHECK(sooc_mapstore_ft_put(s, 0, 999999, 0, 0, v, 100, 1, 0) == SOOC_ENOTFOUND);
    sooc_clearerr();
    float bad[3] = {1, NAN, 2};
    CHECK(sooc_mapstore_ft_put(s, 0, ent[1].id, 0, 0, bad, 3, 1, 0) == SOOC_ENUMERIC);
    sooc_clearerr();
    int found = 0, steps = 0;
    double loss = 0;
    CHECK_OK(sooc_mapstore_ft_get(s, 0, ent[0].id, 0, 0, &found, &steps, &loss));
    CHECK(found == 1 && steps == 120 && loss == -3.25);
    CHECK_OK(sooc_mapstore_ft_get(s, 0, ent[1].id, 0, 0, &found, NULL, NULL));
    CHECK(found == 0);
    sooc_mapstore_close(s);
    /* reopen read-only: the map carries them */
    p.readonly = 1;
    CHECK_OK(sooc_mapstore_open(&s, path, &p));
    if (!s) return;
    sooc_cogmap_destroy(map);
    map = new_map(32, 16);
    CHECK_OK(sooc_mapstore_load_map(s, map));
    size_t n = 0;
    const float *got = sooc_cogmap_payload_get(map, ent[0].id, &n);
    CHECK(got && n == 100 && !memcmp(got, v, sizeof v));
    got = sooc_cogmap_block_payload_get(map, -1, 2, &n);
    CHECK(got && n == 90 && !memcmp(got, v + 10, 90 * sizeof(float)));
    CHECK(sooc_cogmap_payload_get(map, ent[1].id, &n) == NULL && n == 0);
    sooc_mapstore_close(s);
    /* save_map: the map's payloads replace the stored ones */
    p.readonly = 0;
    CHECK_OK(sooc_mapstore_open(&s, path, &p));
    if (!s) return;
    CHECK_OK(sooc_cogmap_payload_set(map, ent[2].id, v + 1, 50));
    CHECK_OK(sooc_cogmap_payload_set(map, ent[0].id, NULL, 0));   /* removed */
    CHECK_OK(sooc_mapstore_save_map(s, map));
    CHECK_OK(sooc_mapstore_ft_count(s, &no, &nb));
    CHECK(no == 1 && nb == 1);
    CHECK_OK(sooc_mapstore_ft_get(s, 0, ent[2].id, 0, 0, &found, NULL, NULL));
    CHECK(found == 1);
    /* deleting an entry deletes its decoder */
    CHECK_OK(sooc_mapstore_begin(s));
    CHECK_OK(sooc_mapstore_remove_entries(s, &ent[2].id, 1));
    CHECK_OK(sooc_mapstore_commit(s));
    CHECK_OK(sooc_mapstore_ft_count(s, &no, &nb));
    CHECK(no == 0 && nb == 1);
    CHECK_OK(sooc_mapstore_ft_put(s, 0, ent[3].id, 0, 0, v, 100, 1, 0));
    sooc_mapstore_close(s);
    /* a corrupt blob: refused, naming the database */
    sqlite3 *db = NULL;
    CHECK(sqlite3_open(path, &db) == SQLITE_OK);
    CHECK(sqlite3_exec(db, "UPDATE ft_objects SET crc = crc + 1", NULL, NULL, NULL) == SQLITE_OK);
    sqlite3_close(db);
    CHECK_OK(sooc_mapstore_open(&s, path, &p));
    if (s) {
        sooc_cogmap *m2 = new_map(32, 16);
        sooc_status st = sooc_mapstore_load_map(s, m2);
        CHECK(st == SOOC_EFORMAT);
        CHECK_MSG(strstr(sooc_errmsg(), path) && strstr(sooc_errmsg(), "corrupt"), "%s", sooc_errmsg());
        sooc_clearerr();
        sooc_cogmap_destroy(m2);
        sooc_mapstore_close(s);
    }
    sooc_cogmap_destroy(map);
    char x[300];
    unlink(path);
    snprintf(x, sizeof x, "%s-wal", path), unlink(x);
    snprintf(x, sizeof x, "%s-shm", path), unlink(x);
}

static double render_sum(sooc_model *m, const sooc_cogmap *map, const double T[16], float *rgb_out) {
    sooc_intrinsics K;
    memset(&K, 0, sizeof K);
    K.width = K.height = 16, K.fx = K.fy = 14, K.cx = K.cy = 8;
    sooc_model_field *f = NULL;
    if (sooc_model_field_create(&f, m, map, T, &K, -1, NULL)) return NAN;
    sooc_render_opts o;
    sooc_render_opts_default(&o);
    o.n_coarse = 32, o.n_fine = 0, o.d_clip = 5, o.threads = 1;
    double T_fc[16];
    sooc_model_field_T_fc(f, T_fc);
    sooc_render_out ro;
    memset(&ro, 0, sizeof ro);
    sooc_status st = sooc_render_view(sooc_model_field_get(f), &K, T_fc, &o, &ro);
    sooc_model_field_destroy(f);
    if (st) return NAN;
    double s = 0;
    for (int i = 0; i < 16 * 16 * 3; i++) s += ro.rgb[i], rgb_out[i] = ro.rgb[i];
    for (int i = 0; i < 16 * 16; i++) s += ro.alpha[i];
    sooc_render_out_free(&ro);
    return s;
}

static void test_field(void) {
    sooc_model_config c;
    synth_tiny_cfg(&c, 2, 1);
    sooc_model *m = NULL;
    CHECK_OK(sooc_model_create(&m, &c, 5));
    if (!m) return;
    /* the untrained layout decoder is a fog everywhere: make it thin so that the object shows */
    sooc_model_params(m)[m->dlay.bd] = -6.0f;
    sooc_cogmap *map = new_map(c.d_what, c.d_layout);
    sooc_cogmap_entry e;
    memset(&e, 0, sizeof e);
    e.X = 0.1, e.Z = 2.5, e.Theta = 0.4, e.rho_t = -4, e.rho_theta = -2, e.pres_logit = 2, e.dim = c.d_what, e.obs_count = 1;
    for (int j = 0; j < c.d_what; j++) e.what_mu[j] = 0.2f * (float)j - 0.3f;
    uint64_t id = 0;
    CHECK_OK(sooc_cogmap_insert(map, &e, &id));
    double T[16];
    synth_pose(T, 0, 1.2, 0, 0, -0.35);
    float a[16 * 16 * 3], b[16 * 16 * 3];
    double s0 = render_sum(m, map, T, a);
    /* the model's own weights and the entry's z as a payload: the same image */
    const float *p = sooc_model_params(m);
    size_t np = sooc_mdl_ft_payload_size(&m->dobj);
    float *pl = malloc(np * sizeof(float));
    sooc_mdl_ft_payload_pack(&m->dobj, MDL_FT_OBJ, e.what_mu, p + m->dobj.W1x, pl);
    CHECK_OK(sooc_cogmap_payload_set(map, id, pl, np));
    double s1 = render_sum(m, map, T, b);
    CHECK_CLOSE(s1, s0, 1e-3, 1e-5);
    double md = 0;
    for (int i = 0; i < 16 * 16 * 3; i++) md = fmax(md, fabs(a[i] - b[i]));
    CHECK_MSG(md < 1e-4, "max |diff| %g", md);
    /* a finetuned copy (denser object): the image changes */
    sooc_dec_net rel;
    sooc_mdl_dec_rel(&m->dobj, &rel);
    pl[MDL_FT_HDR + c.d_what + rel.bd] += 4.0f;   /* denser */
    for (int a3 = 0; a3 < 3; a3++) pl[MDL_FT_HDR + c.d_what + rel.bc2 + a3] += a3 == 1 ? 6.0f : -6.0f;   /* green */
    CHECK_OK(sooc_cogmap_payload_set(map, id, pl, np));
    double s2 = render_sum(m, map, T, b);
    CHECK_MSG(fabs(s2 - s0) > 1.0, "base %.4f finetuned %.4f", s0, s2);
    /* a payload of another shape is ignored */
    CHECK_OK(sooc_cogmap_payload_set(map, id, pl, np - 1));
    double s3 = render_sum(m, map, T, b);
    CHECK_CLOSE(s3, s0, 1e-3, 1e-5);
    /* a layout block payload changes the background */
    CHECK_OK(sooc_cogmap_payload_set(map, id, NULL, 0));
    int32_t bi, bj;
    CHECK_OK(sooc_cogmap_active_block(map, T, c.d_clip, &bi, &bj, NULL));
    size_t npl = sooc_mdl_ft_payload_size(&m->dlay);
    float *ll = malloc(npl * sizeof(float)), zl[SOOC_MODEL_D_MAX];
    memcpy(zl, p + 0, sizeof zl);   /* any z */
    sooc_mdl_ft_payload_pack(&m->dlay, MDL_FT_LAY, zl, p + m->dlay.W1x, ll);
    CHECK_OK(sooc_cogmap_block_payload_set(map, bi, bj, ll, npl));
    double s4 = render_sum(m, map, T, b);
    CHECK(isfinite(s4) && fabs(s4 - s0) > 1e-3);
    CHECK(sooc_cogmap_payload_count(map) == 1);
    sooc_cogmap_clear(map, 0);
    CHECK(sooc_cogmap_payload_count(map) == 0);
    free(ll);
    free(pl);
    sooc_cogmap_destroy(map);
    sooc_model_destroy(m);
}

int main(void) {
    if (!sooc_file_exists(k_fixture)) {
        fprintf(stderr, "test_finetune_store: %s missing (run from the repository root)\n", k_fixture);
        return 1;
    }
    test_store();
    test_field();
    return check_report("test_finetune_store");
}
