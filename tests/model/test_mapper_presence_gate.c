/* The geometric map's presence gate (sooc_mapper_params.min_presence,
 * docs/geometric.md "In the node"):
 *  - change sets replayed into a mirror (changes upserted, removals deleted,
 *    as the table and the store take them) equal the mapper's entries after
 *    every update, with the gate (0.5) and without it (0), on a camera that
 *    pans across three balls on a floor and a large ball beside them that the
 *    views always cut (hidden by the gate);
 *  - with the gate every shown entry has a presence of at least the gate less
 *    the hysteresis, and the gated entries are the ungated run's entries of
 *    presence 0.5 or more (same ids);
 *  - one ball seen whole twice, then only cut by the image's edge, then whole
 *    again: shown, withdrawn (a removal of its id), shown again under the same
 *    id; without the gate it is never removed;
 *  - a resumed entry (loaded into a new mapper) keeps its presence: one cut
 *    view does not withdraw it;
 *  - a gate outside 0..1 is refused. */
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "check.h"
#include "sooc3d/mapper.h"
#include "synth.h"

#define W 80
#define H 60
#define FOV 50.0
#define MAXE 64

typedef struct mirror {
    sooc_map_entry e[MAXE];
    size_t n;
} mirror;

static void mirror_apply(mirror *m, const sooc_mapper *mp) {
    sooc_map_entry chg[SOOC_MAPPER_CHANGED_MAX];
    uint64_t rem[SOOC_MAPPER_CHANGED_MAX];
    size_t nc = 0, nr = 0;
    CHECK_OK(sooc_mapper_changed(mp, chg, SOOC_MAPPER_CHANGED_MAX, &nc, rem, SOOC_MAPPER_CHANGED_MAX, &nr));
    for (size_t i = 0; i < nc; i++) {
        size_t j = 0;
        while (j < m->n && m->e[j].id != chg[i].id) j++;
        if (j == m->n && m->n < MAXE) m->n++;
        if (j < MAXE) m->e[j] = chg[i];
    }
    for (size_t i = 0; i < nr; i++)
        for (size_t j = 0; j < m->n; j++)
            if (m->e[j].id == rem[i]) {
                m->e[j] = m->e[--m->n];
                break;
            }
}

/* The mirror holds exactly the mapper's entries, their positions and presence within what republishes an
 * entry (a move of 3 mm, a presence change of 0.05: mapper_geo.c). */
static int mirror_same(const mirror *m, const sooc_mapper *mp, int step) {
    sooc_map_entry e[MAXE];
    size_t n = 0;
    CHECK_OK(sooc_mapper_entries(mp, e, MAXE, &n));
    int same = n == m->n;
    for (size_t i = 0; i < n && same; i++) {
        int found = 0;
        for (size_t j = 0; j < m->n; j++)
            found |= m->e[j].id == e[i].id && fabs(m->e[j].x - e[i].x) <= 0.003 && fabs(m->e[j].z - e[i].z) <= 0.003 &&
                     fabsf(m->e[j].presence - e[i].presence) <= 0.05f;
        same &= found;
    }
    CHECK_MSG(same, "update %d: the replayed changes hold %zu entries, the mapper %zu", step, m->n, n);
    return same;
}

static sooc_mapper *geo_mapper(double gate) {
    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.kind = SOOC_MAPPER_GEOMETRIC;
    p.input_width = W, p.input_height = H;
    p.min_presence = gate;
    sooc_mapper *mp = NULL;
    CHECK_OK(sooc_mapper_create(&mp, &p));
    return mp;
}

/* Camera 0.55 m up at (cx, 0, -0.9), 35 degrees down, turned by yaw. */
static void view(sooc_frame *f, double cx, double yaw, const synth_sphere *sp, int ns, int64_t i) {
    double T[16];
    synth_pose(T, cx, 0.55, -0.9, yaw, -35.0 * M_PI / 180.0);
    CHECK_OK(synth_frame(f, W, H, FOV, T, sp, ns));
    f->index = i;
    f->t_ns = i * 100000000LL;
}

/* A pan across three balls and a large one off to the side that the views always cut: entries mirrored
 * after each update; the entries (and presence) at the end. */
static size_t pan(double gate, sooc_map_entry *out, int *ok) {
    static const synth_sphere balls[4] = {{{-0.30, 0.05, 0.0}, 0.05, {0.9f, 0.2f, 0.1f}},
                                          {{0.00, 0.06, 0.1}, 0.06, {0.1f, 0.3f, 0.9f}},
                                          {{0.32, 0.04, -0.05}, 0.04, {0.2f, 0.8f, 0.2f}},
                                          {{0.9, 0.2, 0.6}, 0.2, {0.8f, 0.8f, 0.2f}}};
    sooc_mapper *mp = geo_mapper(gate);
    mirror m;
    memset(&m, 0, sizeof m);
    size_t n = 0;
    *ok = mp != NULL;
    for (int i = 0; mp && i < 24; i++) {
        sooc_frame f;
        memset(&f, 0, sizeof f);
        double yaw = 0.55 * sin(i * 0.5), cx = 0.1 * cos(i * 0.3);
        view(&f, cx, yaw, balls, 4, i);
        sooc_update_stats us;
        CHECK_OK(sooc_mapper_update(mp, &f, &us));
        sooc_frame_free(&f);
        mirror_apply(&m, mp);
        *ok &= mirror_same(&m, mp, i);
        for (size_t j = 0; j < m.n; j++)
            CHECK_MSG(m.e[j].presence >= gate - SOOC_MAPPER_PRESENCE_HYST - 1e-6,
                      "gate %.2f, update %d: entry %llu shown at presence %.3f", gate, i,
                      (unsigned long long)m.e[j].id, m.e[j].presence);
    }
    if (mp) CHECK_OK(sooc_mapper_entries(mp, out, MAXE, &n));
    sooc_mapper_destroy(mp);
    return n;
}

/* One update of a mapper on the lone ball, seen whole (the ball straight ahead) or cut (turned by 0.44
 * rad, the image being 50 degrees wide: its centre just inside the left edge, its box beyond it). */
static void ball_step(sooc_mapper *mp, int whole, int64_t i) {
    static const synth_sphere ball = {{0.0, 0.06, 0.0}, 0.06, {0.9f, 0.6f, 0.1f}};
    sooc_frame f;
    memset(&f, 0, sizeof f);
    view(&f, 0.0, whole ? 0.0 : 0.44, &ball, 1, i);
    sooc_update_stats us;
    CHECK_OK(sooc_mapper_update(mp, &f, &us));
    sooc_frame_free(&f);
}

/* One ball: `pattern` says per update whether it is seen whole (1) or cut by the image's edge (0).
 * Returns how often its id was reported removed and shown (a change after a removal), and whether it is
 * an entry at the end. */
static void one_ball(double gate, const char *pattern, int *n_removed, int *n_reshown, int *at_end, uint64_t *id) {
    sooc_mapper *mp = geo_mapper(gate);
    *n_removed = *n_reshown = *at_end = 0;
    *id = 0;
    int gone = 0;
    for (int i = 0; mp && pattern[i]; i++) {
        ball_step(mp, pattern[i] == '1', i);
        sooc_map_entry chg[SOOC_MAPPER_CHANGED_MAX];
        uint64_t rem[SOOC_MAPPER_CHANGED_MAX];
        size_t nc = 0, nr = 0;
        CHECK_OK(sooc_mapper_changed(mp, chg, SOOC_MAPPER_CHANGED_MAX, &nc, rem, SOOC_MAPPER_CHANGED_MAX, &nr));
        for (size_t k = 0; k < nr; k++) (*n_removed)++, gone = 1;
        for (size_t k = 0; k < nc; k++) {
            if (!*id) *id = chg[k].id;
            CHECK_MSG(chg[k].id == *id, "a second entry %llu for one ball", (unsigned long long)chg[k].id);
            if (gone) (*n_reshown)++, gone = 0;
        }
        sooc_map_entry e[MAXE];
        size_t n = 0;
        CHECK_OK(sooc_mapper_entries(mp, e, MAXE, &n));
        printf("  gate %.1f, view %2d (%s): %zu entr%s, presence %.3f%s\n", gate, i, pattern[i] == '1' ? "whole" : "cut",
               n, n == 1 ? "y" : "ies", n ? e[0].presence : NAN, nr ? " (removed)" : "");
        *at_end = n == 1;
    }
    sooc_mapper_destroy(mp);
}

int main(void) {
    sooc_map_entry all[MAXE], gated[MAXE];
    int ok_all = 0, ok_gated = 0;
    size_t n_all = pan(0.0, all, &ok_all), n_gated = pan(0.5, gated, &ok_gated);
    printf("pan across four balls: %zu entries without the gate, %zu with it\n", n_all, n_gated);
    CHECK(ok_all && ok_gated && n_all >= 4);
    CHECK_MSG(n_gated < n_all, "the gate hid nothing: the check cannot fail");
    for (size_t i = 0; i < n_all; i++) {
        int found = 0;
        for (size_t j = 0; j < n_gated; j++) found |= gated[j].id == all[i].id;
        printf("  entry %llu: presence %.3f, %s\n", (unsigned long long)all[i].id, all[i].presence,
               found ? "shown" : "hidden");
        if (all[i].presence >= 0.5f) CHECK_MSG(found, "entry %llu (presence %.3f) hidden by the gate",
                                               (unsigned long long)all[i].id, all[i].presence);
        if (all[i].presence < 0.5f - SOOC_MAPPER_PRESENCE_HYST)
            CHECK_MSG(!found, "entry %llu (presence %.3f) shown", (unsigned long long)all[i].id, all[i].presence);
    }
    for (size_t j = 0; j < n_gated; j++) {
        int found = 0;
        for (size_t i = 0; i < n_all; i++) found |= gated[j].id == all[i].id;
        CHECK_MSG(found, "gated entry %llu is not an entry without the gate", (unsigned long long)gated[j].id);
    }

    /* seen whole twice (presence 0.75), cut six times (0.30: withdrawn), whole twelve times (0.68: shown) */
    const char *pattern = "11000000111111111111";
    int nrem, nre, at_end;
    uint64_t id;
    one_ball(0.5, pattern, &nrem, &nre, &at_end, &id);
    printf("one ball, gate 0.5: entry %llu removed %d time(s), shown again %d time(s), %s at the end\n",
           (unsigned long long)id, nrem, nre, at_end ? "an entry" : "no entry");
    CHECK_MSG(id && nrem == 1 && nre == 1 && at_end, "gate 0.5: removed %d, shown again %d, at end %d", nrem, nre,
              at_end);
    one_ball(0.0, pattern, &nrem, &nre, &at_end, &id);
    CHECK_MSG(id && nrem == 0 && at_end, "no gate: removed %d, at end %d", nrem, at_end);

    /* a resumed map: the ball's entry after the pattern, loaded into a new mapper, seen cut once: its
     * presence goes on from the stored one (not from a first view: 1 / 3), so it stays shown */
    {
        sooc_mapper *a = geo_mapper(0.5), *b = geo_mapper(0.5);
        sooc_map_entry e[MAXE], e2[MAXE];
        size_t n = 0, n2 = 0;
        for (int i = 0; a && pattern[i]; i++) ball_step(a, pattern[i] == '1', i);
        if (a) CHECK_OK(sooc_mapper_entries(a, e, MAXE, &n));
        CHECK(n == 1);
        if (b && n == 1) {
            CHECK_OK(sooc_mapper_load_entries(b, e, n));
            ball_step(b, 0, 100);
            CHECK_OK(sooc_mapper_entries(b, e2, MAXE, &n2));
            printf("resumed: presence %.3f, after one cut view %s %.3f\n", e[0].presence, n2 ? "shown at" : "withdrawn",
                   n2 ? e2[0].presence : NAN);
            CHECK_MSG(n2 == 1 && e2[0].id == e[0].id && fabsf(e2[0].presence - e[0].presence) < 0.05f,
                      "resumed entry: %zu entries after one cut view", n2);
        }
        sooc_mapper_destroy(a);
        sooc_mapper_destroy(b);
    }

    sooc_mapper_params p;
    sooc_mapper_params_default(&p);
    p.kind = SOOC_MAPPER_GEOMETRIC;
    p.min_presence = 1.5;
    sooc_mapper *bad = NULL;
    CHECK(sooc_mapper_create(&bad, &p) == SOOC_EINVAL && bad == NULL);
    CHECK(strstr(sooc_errmsg(), "min_presence") != NULL);
    sooc_clearerr();
    return check_report("test_mapper_presence_gate");
}
