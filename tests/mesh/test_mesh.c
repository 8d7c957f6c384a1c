/* Marching cubes on analytic fields (include/sooc3d/render.h): a sphere and a
 * box give the analytic volume and area within 1%, every mesh is watertight
 * and consistently wound (each edge once in each direction, signed volume
 * positive), a noise field full of ambiguous cells is still closed, the
 * result does not depend on the thread count, frames are applied, and the
 * PLY round trip reads back what was written (here and by a small Python
 * reader, skipped without python3). */
#include "check.h"
#include "sooc3d/core.h"
#include "sooc3d/render.h"

#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

typedef struct afield {
    int kind;            /* 0 sphere, 1 box, 2 noise, 3 everywhere inside */
    double c[3], r;      /* sphere */
    double T_be[16];     /* eval frame -> box frame */
    double h[3];         /* box half extents */
    double w;            /* ramp width */
    double step;         /* noise grid step */
} afield;

static double clamp01(double x) { return x < 0 ? 0 : x > 1 ? 1 : x; }

static uint32_t hash3(long i, long j, long k) {
    uint64_t x = (uint64_t)(i * 73856093L) ^ (uint64_t)(j * 19349663L) ^ (uint64_t)(k * 83492791L);
    x ^= x >> 33;
    x *= 0xff51afd7ed558ccdULL;
    x ^= x >> 33;
    return (uint32_t)x;
}

static void a_eval(void *user, int worker, int comp, const float *pts, int n, float *sig, float *rgb) {
    (void)worker, (void)comp;
    const afield *a = user;
    for (int i = 0; i < n; i++) {
        const float *p = pts + 3 * i;
        double v = 0;
        if (a->kind == 0) {
            double dx = p[0] - a->c[0], dy = p[1] - a->c[1], dz = p[2] - a->c[2];
            v = 0.5 + (a->r - sqrt(dx * dx + dy * dy + dz * dz)) / a->w;
        } else if (a->kind == 1) {
            double q[3], o = 0, in = -1e9;
            for (int r = 0; r < 3; r++)
                q[r] = a->T_be[4 * r] * p[0] + a->T_be[4 * r + 1] * p[1] + a->T_be[4 * r + 2] * p[2] + a->T_be[4 * r + 3];
            for (int r = 0; r < 3; r++) {
                double d = fabs(q[r]) - a->h[r];
                if (d > 0) o += d * d;
                if (d > in) in = d;
            }
            double sdf = o > 0 ? sqrt(o) : in;
            v = 0.5 - sdf / a->w;
        } else if (a->kind == 2) {
            long i0 = lround(p[0] / a->step), j0 = lround(p[1] / a->step), k0 = lround(p[2] / a->step);
            v = (hash3(i0, j0, k0) & 0xffff) / 65535.0;
        } else {
            v = 1;
        }
        sig[i] = (float)clamp01(v);
        rgb[3 * i] = (float)clamp01(p[0] + 0.5), rgb[3 * i + 1] = (float)clamp01(p[1]), rgb[3 * i + 2] = 0.25f;
    }
}

static sooc_field make_field(afield *a) {
    sooc_field f;
    memset(&f, 0, sizeof f);
    f.n_comp = 1;
    f.sigma_max = 30;
    f.eval = a_eval;
    f.user = a;
    return f;
}

static void grid_cube(sooc_mesh_grid *g, double lo, double hi, int res) {
    memset(g, 0, sizeof *g);
    sooc_se3_identity(g->T_eg);
    sooc_se3_identity(g->T_og);
    for (int d = 0; d < 3; d++) g->lo[d] = lo, g->hi[d] = hi, g->res[d] = res;
}

static void check_closed(const sooc_mesh *m, const char *what) {
    size_t bad = 0;
    int ok = sooc_mesh_is_closed(m, &bad);
    CHECK_MSG(ok, "%s: %zu edges not shared by exactly two triangles in opposite directions", what, bad);
    CHECK_MSG(m->n_tri > 0, "%s: empty mesh", what);
}

static void test_sphere(void) {
    afield a = {0};
    a.kind = 0, a.c[0] = 0.013, a.c[1] = -0.021, a.c[2] = 0.007, a.r = 0.3, a.w = 0.2;
    sooc_field f = make_field(&a);
    sooc_mesh_grid g;
    grid_cube(&g, -0.4, 0.4, 64);
    sooc_mesh m = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    double V = sooc_mesh_volume(&m), A = sooc_mesh_area(&m);
    double V0 = 4.0 / 3.0 * M_PI * a.r * a.r * a.r, A0 = 4 * M_PI * a.r * a.r;
    printf("sphere r 0.3, 64^3 over 0.8 m: %zu vertices, %zu triangles, volume %.6f (analytic %.6f, %+.3f%%), "
           "area %.6f (analytic %.6f, %+.3f%%)\n",
           m.n_vert, m.n_tri, V, V0, 100 * (V / V0 - 1), A, A0, 100 * (A / A0 - 1));
    CHECK_CLOSE(V, V0, 0, 0.01);
    CHECK_CLOSE(A, A0, 0, 0.01);
    CHECK(V > 0);
    check_closed(&m, "sphere");
    /* every vertex on the sphere (the field is linear in the distance) */
    double worst = 0;
    for (size_t i = 0; i < m.n_vert; i++) {
        double dx = m.xyz[3 * i] - a.c[0], dy = m.xyz[3 * i + 1] - a.c[1], dz = m.xyz[3 * i + 2] - a.c[2];
        double e = fabs(sqrt(dx * dx + dy * dy + dz * dz) - a.r);
        if (e > worst) worst = e;
    }
    CHECK_MSG(worst < 1e-3, "worst vertex distance from the sphere %g m", worst);
    /* vertex colour = the field's colour at the vertex */
    size_t k = m.n_vert / 2;
    CHECK(abs((int)m.rgb[3 * k] - (int)lrint(clamp01(m.xyz[3 * k] + 0.5) * 255)) <= 1);
    CHECK(m.rgb[3 * k + 2] == 64);
    /* no duplicate vertices: each vertex is used, and no two share a position */
    {
        size_t dup = 0;
        for (size_t i = 1; i < m.n_vert && i < 2000; i++)
            for (size_t j = 0; j < i; j++)
                if (!memcmp(m.xyz + 3 * i, m.xyz + 3 * j, 12)) dup++;
        CHECK_MSG(dup == 0, "%zu duplicate vertices among the first 2000", dup);
        uint8_t *used = calloc(m.n_vert, 1);
        for (size_t t = 0; t < 3 * m.n_tri; t++) used[m.tri[t]] = 1;
        size_t unused = 0;
        for (size_t i = 0; i < m.n_vert; i++) unused += !used[i];
        CHECK_MSG(unused == 0, "%zu unused vertices", unused);
        free(used);
    }
    /* thread count does not change the mesh */
    sooc_mesh m1 = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 1, &m1));
    CHECK(m1.n_vert == m.n_vert && m1.n_tri == m.n_tri);
    if (m1.n_vert == m.n_vert && m1.n_tri == m.n_tri) {
        CHECK(!memcmp(m1.xyz, m.xyz, m.n_vert * 12));
        CHECK(!memcmp(m1.rgb, m.rgb, m.n_vert * 3));
        CHECK(!memcmp(m1.tri, m.tri, m.n_tri * 12));
    }
    /* a coarse grid: still closed */
    grid_cube(&g, -0.4, 0.4, 9);
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m1));
    check_closed(&m1, "sphere 9^3");
    CHECK(sooc_mesh_volume(&m1) > 0);
    sooc_mesh_free(&m1);
    sooc_mesh_free(&m);
}

static void test_box(void) {
    afield a = {0};
    a.kind = 1, a.h[0] = 0.2, a.h[1] = 0.15, a.h[2] = 0.1, a.w = 0.2;
    /* the box stands rotated in the eval frame: T_eb = R_y(0.5) + t; the grid is laid out in the box frame */
    double R[9], t[3] = {0.3, 0.15, -0.2}, T_eb[16];
    sooc_m3_rot_y(R, 0.5);
    sooc_se3_from_rt(T_eb, R, t);
    sooc_se3_inverse(a.T_be, T_eb);
    sooc_field f = make_field(&a);
    sooc_mesh_grid g;
    grid_cube(&g, -0.2513, 0.2487, 161);
    memcpy(g.T_eg, T_eb, sizeof T_eb);
    double Ro[9], to[3] = {1, 2, 3};
    sooc_m3_rot_y(Ro, -1.0);
    sooc_se3_from_rt(g.T_og, Ro, to);
    sooc_mesh m = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    double V = sooc_mesh_volume(&m), A = sooc_mesh_area(&m);
    double V0 = 8 * a.h[0] * a.h[1] * a.h[2], A0 = 8 * (a.h[0] * a.h[1] + a.h[1] * a.h[2] + a.h[0] * a.h[2]);
    printf("box 0.4 x 0.3 x 0.2, 161^3 over 0.5 m: %zu vertices, %zu triangles, volume %.6f (analytic %.6f, %+.3f%%), "
           "area %.6f (analytic %.6f, %+.3f%%)\n",
           m.n_vert, m.n_tri, V, V0, 100 * (V / V0 - 1), A, A0, 100 * (A / A0 - 1));
    CHECK_CLOSE(V, V0, 0, 0.01);
    CHECK_CLOSE(A, A0, 0, 0.01);
    check_closed(&m, "box");
    /* vertices are written through T_og: the box centre lands at (1, 2, 3) */
    double c[3] = {0, 0, 0};
    for (size_t i = 0; i < m.n_vert; i++)
        for (int d = 0; d < 3; d++) c[d] += m.xyz[3 * i + d] / (double)m.n_vert;
    CHECK_CLOSE(c[0], 1, 0.01, 0);
    CHECK_CLOSE(c[1], 2, 0.01, 0);
    CHECK_CLOSE(c[2], 3, 0.01, 0);
    sooc_mesh_free(&m);
}

static void test_noise_and_border(void) {
    afield a = {0};
    a.kind = 2, a.step = 0.05;
    sooc_field f = make_field(&a);
    sooc_mesh_grid g;
    grid_cube(&g, -0.5, 0.5, 21);   /* samples on the noise lattice: every cell configuration occurs */
    sooc_mesh m = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    check_closed(&m, "noise");
    CHECK(sooc_mesh_volume(&m) > 0);
    printf("noise field 21^3: %zu triangles, closed %d\n", m.n_tri, sooc_mesh_is_closed(&m, NULL));
    /* density inside everywhere: the surface is the grid's border (capped), volume = the grid box */
    a.kind = 3;
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    check_closed(&m, "full");
    CHECK_CLOSE(sooc_mesh_volume(&m), 1.0, 1e-5, 0);
    CHECK_CLOSE(sooc_mesh_area(&m), 6.0, 1e-4, 0);
    /* nothing inside: an empty mesh, no error */
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, 2.0f, 0, &m));
    CHECK(m.n_vert == 0 && m.n_tri == 0);
    /* bad grids are errors that say why */
    g.res[1] = 1;
    CHECK(sooc_mesh_extract(&f, 0, &g, 0.5f, 0, &m) == SOOC_EINVAL);
    sooc_clearerr();
    sooc_mesh_free(&m);
}

static void test_ply(void) {
    afield a = {0};
    a.kind = 0, a.r = 0.2, a.w = 0.2;
    sooc_field f = make_field(&a);
    sooc_mesh_grid g;
    grid_cube(&g, -0.3, 0.3, 24);
    sooc_mesh m = {0}, r = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    char dir[] = "/tmp/test_mesh_XXXXXX", path[256];
    if (!mkdtemp(dir)) {
        CHECK(0);
        return;
    }
    snprintf(path, sizeof path, "%s/sphere.ply", dir);
    CHECK_OK(sooc_mesh_write_ply(&m, path, "test sphere\nsecond line"));
    CHECK_OK(sooc_mesh_read_ply(path, &r));
    CHECK(r.n_vert == m.n_vert && r.n_tri == m.n_tri);
    if (r.n_vert == m.n_vert && r.n_tri == m.n_tri) {
        CHECK(!memcmp(r.xyz, m.xyz, m.n_vert * 12));
        CHECK(!memcmp(r.rgb, m.rgb, m.n_vert * 3));
        CHECK(!memcmp(r.tri, m.tri, m.n_tri * 12));
    }
    /* a truncated file is an error naming the file */
    {
        FILE *fp = fopen(path, "r+b");
        if (fp) {
            fseek(fp, 0, SEEK_END);
            long n = ftell(fp);
            fclose(fp);
            CHECK(truncate(path, n - 7) == 0);
            CHECK(sooc_mesh_read_ply(path, &r) == SOOC_EFORMAT);
            CHECK(strstr(sooc_errmsg(), "sphere.ply") != NULL);
            sooc_clearerr();
            CHECK_OK(sooc_mesh_write_ply(&m, path, NULL));
        }
    }
    /* an independent reader: Python's struct module */
    if (system("python3 -c 'import struct' >/dev/null 2>&1") != 0) {
        printf("SKIP the Python PLY reader: no python3\n");
    } else {
        char cmd[2048];
        snprintf(cmd, sizeof cmd,
                 "python3 -c \"\n"
                 "import struct,sys\n"
                 "b=open('%s','rb').read(); h=b.index(b'end_header\\n')+11; hd=b[:h].decode().split('\\n')\n"
                 "assert hd[0]=='ply' and hd[1]=='format binary_little_endian 1.0'\n"
                 "nv=[int(l.split()[2]) for l in hd if l.startswith('element vertex')][0]\n"
                 "nf=[int(l.split()[2]) for l in hd if l.startswith('element face')][0]\n"
                 "V=[struct.unpack_from('<fffBBB',b,h+15*i) for i in range(nv)]; o=h+15*nv; vol=0.0\n"
                 "for t in range(nf):\n"
                 "  n,i,j,k=struct.unpack_from('<Biii',b,o+13*t); assert n==3\n"
                 "  a,c,d=V[i],V[j],V[k]\n"
                 "  vol+=(a[0]*(c[1]*d[2]-c[2]*d[1])-a[1]*(c[0]*d[2]-c[2]*d[0])+a[2]*(c[0]*d[1]-c[1]*d[0]))/6\n"
                 "assert o+13*nf==len(b)\n"
                 "print('%%d %%d %%.6f'%%(nv,nf,vol))\" > %s/py.txt",
                 path, dir);
        int rc = system(cmd);
        CHECK_MSG(rc == 0, "the Python PLY reader failed (%d)", rc);
        char pyout[256];
        snprintf(pyout, sizeof pyout, "%s/py.txt", dir);
        FILE *fp = fopen(pyout, "r");
        size_t nv = 0, nf = 0;
        double vol = 0;
        CHECK(fp && fscanf(fp, "%zu %zu %lf", &nv, &nf, &vol) == 3);
        if (fp) fclose(fp);
        CHECK(nv == m.n_vert && nf == m.n_tri);
        CHECK_CLOSE(vol, sooc_mesh_volume(&m), 1e-6, 1e-4);
        printf("Python reader: %zu vertices, %zu faces, volume %.6f\n", nv, nf, vol);
        remove(pyout);
    }
    remove(path);
    rmdir(dir);
    sooc_mesh_free(&m);
    sooc_mesh_free(&r);
}

/* The metric's pieces: points on a true surface (a generator sphere and box)
 * lie on it and cover it, and a marching-cubes mesh of the same shape is
 * within a few millimetres of them both ways; a shifted copy is not. */
static void test_metric(void) {
    sooc_scene_object o;
    memset(&o, 0, sizeof o);
    o.id = 1, o.shape = SOOC_SHAPE_SPHERE, o.x = 0.4, o.z = -0.3, o.params[0] = 0.3;
    o.size[0] = o.size[1] = o.size[2] = 0.6;
    float *gt = NULL;
    size_t ngt = 0;
    CHECK_OK(sooc_mesh_gt_points(&o, 0.02, 1, &gt, &ngt));
    double worst = 0;
    for (size_t i = 0; i < ngt; i++) {
        double p[3] = {gt[3 * i], gt[3 * i + 1], gt[3 * i + 2]};
        double d = sooc_scene_object_distance(&o, p);
        if (d > worst) worst = d;
    }
    /* 2 cm voxel centroids of a sphere lie at most ~1 mm inside it; about one point per 4 cm^2 */
    CHECK_MSG(worst < 2e-3, "a GT point lies %g m from the sphere", worst);
    double area = 4 * M_PI * 0.09;
    CHECK_MSG(ngt > 0.7 * area / 4e-4 && ngt < 2.5 * area / 4e-4, "%zu GT points for %.3f m^2", ngt, area);
    afield a = {0};
    a.kind = 0, a.c[0] = o.x, a.c[1] = 0.3, a.c[2] = o.z, a.r = 0.3, a.w = 0.2;
    sooc_field f = make_field(&a);
    sooc_mesh_grid g;
    grid_cube(&g, -0.35, 0.35, 64);
    g.T_eg[3] = o.x, g.T_eg[7] = 0.3, g.T_eg[11] = o.z;
    memcpy(g.T_og, g.T_eg, sizeof g.T_og);
    sooc_mesh m = {0};
    CHECK_OK(sooc_mesh_extract(&f, 0, &g, SOOC_MESH_LEVEL, 0, &m));
    float *pred = malloc(20000 * 3 * sizeof(float));
    CHECK_OK(sooc_mesh_sample(&m, 20000, 7, pred));
    sooc_mesh_metric r;
    CHECK_OK(sooc_mesh_acc_comp(pred, 20000, gt, ngt, &r));
    printf("sphere mesh vs true sphere: acc %.3f cm, comp %.3f cm, F %.3f (%zu GT points)\n", r.acc_cm, r.comp_cm,
           r.fscore, ngt);
    CHECK(r.acc_cm < 1.0 && r.comp_cm < 1.0 && r.fscore > 0.999);   /* 2 cm voxels: ~0.4-0.7 cm */
    /* 10 cm off: both distances grow to several cm */
    for (size_t i = 0; i < 20000; i++) pred[3 * i] += 0.1f;
    CHECK_OK(sooc_mesh_acc_comp(pred, 20000, gt, ngt, &r));
    CHECK(r.acc_cm > 3 && r.comp_cm > 3 && r.fscore < 0.8);
    sooc_free(gt);
    /* a box (yawed): points on its faces */
    memset(&o, 0, sizeof o);
    o.id = 2, o.shape = SOOC_SHAPE_BOX, o.x = -1, o.z = 2, o.yaw = 0.6;
    o.params[0] = 0.2, o.params[1] = 0.15, o.params[2] = 0.1;
    o.size[0] = 0.4, o.size[1] = 0.3, o.size[2] = 0.2;
    CHECK_OK(sooc_mesh_gt_points(&o, 0.02, 1, &gt, &ngt));
    worst = 0;
    for (size_t i = 0; i < ngt; i++) {
        double p[3] = {gt[3 * i], gt[3 * i + 1], gt[3 * i + 2]};
        double d = sooc_scene_object_distance(&o, p);
        if (d > worst) worst = d;
    }
    area = 8 * (0.2 * 0.15 + 0.15 * 0.1 + 0.2 * 0.1);
    CHECK_MSG(worst < 6e-3, "a GT point lies %g m from the box", worst);
    CHECK_MSG(ngt > 0.7 * area / 4e-4 && ngt < 2.5 * area / 4e-4, "%zu GT points for %.3f m^2", ngt, area);
    sooc_free(gt);
    free(pred);
    sooc_mesh_free(&m);
}

int main(void) {
    test_metric();
    test_sphere();
    test_box();
    test_noise_and_border();
    test_ply();
    return check_report("test_mesh");
}
