/*
 * A cognitive-map entry as the mapper hands it out (world frame, metres,
 * standard deviations), and its conversions to and from the cognitive map's
 * own entry (sooc3d/cogmap.h: log-variances, the rows of the SQLite map
 * store). Implemented in src/cogmap/map_entry.c, so anything that links the
 * cogmap module (the node with a real or a fake mapper, the CLI, the model's
 * mapper) shares one definition.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_MAP_ENTRY_H
#define SOOC3D_MAP_ENTRY_H

#include "sooc3d/cogmap.h"
#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

#define SOOC_MAP_LATENT_MAX 32

/* Object geometry for planners (docs/shm.md "How each field is
 * computed"; src/mapper/objgeom.c). flags 0 = not computed: extent is then
 * the model's locality box and the spreads are the posterior's. */
#define SOOC_GEOM_TIGHT 0x1u      /* extent and centre: the tight box of the object's own density */
#define SOOC_GEOM_SYMMETRIC 0x2u  /* rotationally symmetric about its vertical axis: yaw undefined */
#define SOOC_GEOM_EMPTY 0x4u      /* no density at the surface level in its box (extent 0) */
#define SOOC_GEOM_CLIPPED 0x8u    /* the density reaches the locality box's side: extent cut there */
#define SOOC_GEOM_FAINT 0x10u     /* below the surface level everywhere: the box at half its peak density */
typedef struct sooc_map_geometry {
    uint32_t flags;            /* SOOC_GEOM_* */
    float centre[3];           /* tight box centre in the object frame (m); centre[1] = height above the floor */
    float sym_iou;             /* rotational self-overlap of the density (symmetric when >= SOOC_OBJGEOM_SYM_IOU) */
    double cov_xz[3];          /* position covariance xx xz zz (m^2, world), calibrated (objgeom.h) */
    double var_yaw;            /* yaw variance (rad^2); NaN = undefined (SYMMETRIC) */
    uint32_t reg_n;            /* registrations in the spread statistics */
    double reg_mean[2];        /* their mean floor position (X, Z) */
    double reg_m2[3];          /* Welford sums of squares xx xz zz about it */
    double reg_cs[2];          /* sums of cos / sin of their yaw */
} sooc_map_geometry;

/* One cognitive-map entry in the world frame (+y up, floor y = 0). */
typedef struct sooc_map_entry {
    uint64_t id;               /* stable, never reused; starts at 1 */
    double x, z, yaw;          /* posterior mean of z^where in the world frame (m, m, rad) */
    double sigma_t, sigma_yaw; /* posterior std of position (shared by x and z) and yaw */
    float presence;            /* sigmoid of the presence logit */
    float presence_logit;
    int latent_dim;            /* <= SOOC_MAP_LATENT_MAX */
    float what_mu[SOOC_MAP_LATENT_MAX];
    float what_logvar[SOOC_MAP_LATENT_MAX];
    float extent[3];           /* box size (x, y, z) in m: the tight box (geom.flags TIGHT) or the model's locality box */
    int64_t first_seen_ns, last_seen_ns;
    uint32_t obs_count;
    sooc_map_geometry geom;    /* tight box, height, spreads (zero: not computed) */
} sooc_map_entry;

/* Conversions between a map entry and the cognitive map's entry (the rows of
 * the SQLite map store): the one definition the mapper, the node (also when
 * it links a fake mapper) and the CLI share; src/cogmap/map_entry.c.
 *
 * from_cogmap: sigma = exp(rho / 2), presence = sigmoid(logit), latent_dim
 *   clamped to [0, SOOC_MAP_LATENT_MAX]. The cogmap does not store the box
 *   extent: it is copied from `extent` (the model's box, or the one stored
 *   with a map; NULL = zeros).
 * to_cogmap: rho = 2 log(max(sigma, 1e-12)), latent_dim clamped to
 *   [0, SOOC_COGMAP_DIM_MAX], obs_count >= 1 (an entry in a map has been
 *   registered at least once: the cogmap invariant), last_view = -1 (a map
 *   entry does not carry it; -1 = not registered by a view of this session,
 *   where 0 would claim view 0). The extent is dropped. */
void sooc_map_entry_from_cogmap(const sooc_cogmap_entry *c, const float extent[3], sooc_map_entry *e);

/* The uncertainty a planner gets, the same in the shm table, `sooc3d map
 * list` and the CSV / JSON export (docs/shm.md "How each field is computed"):
 * the calibrated spreads of e->geom when computed (cov_xz, var_yaw; var_yaw
 * NaN for a symmetric shape), else the posterior's sigma_t^2 (x and z, no
 * correlation) and sigma_yaw^2. cov = {xx, xz, zz, yaw yaw}; returns 1 when
 * the calibrated spreads were used. */
int sooc_map_entry_planner_cov(const sooc_map_entry *e, double cov[4]);
/* The largest yaw variance published: that of an angle uniform on the
 * circle, (2 pi)^2 / 12 = pi^2 / 3 rad^2 (a yaw known not at all). */
#define SOOC_MAP_YAW_VAR_MAX 3.289868133696453

/* The planner's box of an entry, as the shm table publishes it: centre
 * (x, y, z) in the world frame (y above the floor: the tight box's centre
 * height when computed, else half the extent), rotation yaw about +y, full
 * extent ext (m) along the box's own axes. */
void sooc_map_entry_box(const sooc_map_entry *e, double centre[3], double *yaw, float ext[3]);

/* The box-quality words of geom.flags for people and exports: "tight",
 * "tight,clipped", "empty", "faint", "not computed", ... (buf >= 48). */
const char *sooc_map_entry_box_quality(const sooc_map_geometry *g, char *buf, size_t cap);
void sooc_map_entry_to_cogmap(const sooc_map_entry *e, sooc_cogmap_entry *c);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_MAP_ENTRY_H */
