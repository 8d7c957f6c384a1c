/* sooc_cogmap_merge_neighbours (the node's revisit rule): a registered entry
 * next to an unregistered one becomes one entry with the better-observed id,
 * where / what means weighted by both observation counts; entries farther than the radius are untouched. */
#include "check.h"
#include "sooc3d/cogmap.h"

#include <string.h>

static void put(sooc_cogmap *m, uint64_t id, double X, double Z, uint32_t obs, int64_t first) {
    sooc_cogmap_entry e;
    memset(&e, 0, sizeof e);
    e.id = id;
    e.X = X;
    e.Z = Z;
    e.dim = 4;
    e.pres_logit = 3;
    e.obs_count = obs;
    e.first_seen_ns = e.last_seen_ns = first;
    e.what_mu[0] = (float)id;
    CHECK_OK(sooc_cogmap_insert(m, &e, NULL));
}

int main(void) {
    sooc_cogmap_params p;
    sooc_cogmap_params_default(&p);
    p.dim = 4;
    p.layout_dim = 0;
    sooc_cogmap *m = NULL;
    CHECK_OK(sooc_cogmap_create(&m, &p));
    if (!m) return check_report("test_cogmap_revisit");
    put(m, 1, 0.0, 0.0, 5, 100);    /* mapped earlier, not retrieved by the view */
    put(m, 2, 0.2, 0.0, 1, 900);    /* the view's new entry for the same object */
    put(m, 3, 3.9, 0.1, 2, 200);    /* registered, on a cell border, nothing near */
    put(m, 4, 4.05, 0.1, 7, 300);   /* unregistered, 0.15 m from 3 across the cell border: 4 stays (more obs) */
    put(m, 5, 9.0, 9.0, 1, 400);    /* far away: untouched */
    uint64_t ids[4] = {2, 0, 3, 0}, rem[4] = {0};
    int nr = -1;
    CHECK_OK(sooc_cogmap_merge_neighbours(m, ids, 4, 0.35, rem, 4, &nr));
    CHECK(nr == 2);
    CHECK(ids[0] == 1 && ids[2] == 4);
    CHECK(rem[0] == 2 && rem[1] == 3);
    sooc_cogmap_entry e;
    CHECK_OK(sooc_cogmap_get(m, 1, &e));
    /* where / what means weighted by observation counts: (5 x 0.0 + 1 x 0.2) / 6 */
    CHECK(e.obs_count == 6 && e.first_seen_ns == 100);
    CHECK_CLOSE(e.X, 0.2 / 6.0, 1e-12, 0);
    CHECK_CLOSE(e.what_mu[0], 7.0 / 6.0, 1e-6, 0);
    CHECK_OK(sooc_cogmap_get(m, 4, &e));
    CHECK(e.obs_count == 9 && e.first_seen_ns == 200);
    CHECK_CLOSE(e.X, (2 * 3.9 + 7 * 4.05) / 9.0, 1e-12, 0);
    CHECK_CLOSE(e.what_mu[0], (2 * 3.0 + 7 * 4.0) / 9.0, 1e-6, 0);
    CHECK(sooc_cogmap_get(m, 2, &e) == SOOC_ENOTFOUND && sooc_cogmap_get(m, 3, &e) == SOOC_ENOTFOUND);
    CHECK_OK(sooc_cogmap_get(m, 5, &e));
    CHECK(e.X == 9.0 && e.obs_count == 1);
    /* a second call finds nothing more; radius 0 does nothing; cap 0 does nothing */
    CHECK_OK(sooc_cogmap_merge_neighbours(m, ids, 4, 0.35, rem, 4, &nr));
    CHECK(nr == 0);
    put(m, 6, 9.1, 9.0, 1, 500);
    uint64_t ids2[1] = {6};
    CHECK_OK(sooc_cogmap_merge_neighbours(m, ids2, 1, 0.0, rem, 4, &nr));
    CHECK(nr == 0 && ids2[0] == 6);
    CHECK_OK(sooc_cogmap_merge_neighbours(m, ids2, 1, 0.35, rem, 0, &nr));
    CHECK(nr == 0 && ids2[0] == 6);
    CHECK_OK(sooc_cogmap_merge_neighbours(m, ids2, 1, 0.35, NULL, 4, &nr));
    CHECK(nr == 1 && ids2[0] == 5);
    sooc_cogmap_destroy(m);
    return check_report("test_cogmap_revisit");
}
