/* Data-parallel training over MPI: the few collectives the trainer needs
 * (include/sooc3d/model.h). Everything MPI is in this file; without
 * SOOC_HAVE_MPI the same functions describe a world of one rank. */
#include "sooc3d/model.h"

#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#ifdef SOOC_HAVE_MPI
#include <mpi.h>
#endif

static int g_rank = 0, g_size = 1;
static char g_host[256] = "localhost";

static int env_int(const char *name) {
    const char *v = getenv(name);
    return v && *v ? atoi(v) : 0;
}

/* The number of tasks the launcher says the job has (0 if none says). */
static int launcher_size(void) {
    int n = env_int("OMPI_COMM_WORLD_SIZE");
    if (n <= 0) n = env_int("PMI_SIZE");
    if (n <= 0) n = env_int("SLURM_STEP_NUM_TASKS");
    return n;
}

int sooc_dist_rank(void) { return g_rank; }
int sooc_dist_size(void) { return g_size; }
const char *sooc_dist_host(void) { return g_host; }

#ifdef SOOC_HAVE_MPI

int sooc_dist_compiled(void) { return 1; }

static int g_started = 0;

/* 1 if an MPI launcher started this process: Open MPI's mpirun, or PMI/PMIx
 * (srun --mpi=pmix / pmi2, MPICH's hydra). */
static int under_mpi_launcher(void) {
    return getenv("OMPI_COMM_WORLD_SIZE") || getenv("PMIX_RANK") || getenv("PMI_RANK");
}


static sooc_status mpi_fail(int rc, const char *call, const char *what) {
    char es[MPI_MAX_ERROR_STRING];
    int len = 0;
    if (MPI_Error_string(rc, es, &len) != MPI_SUCCESS) snprintf(es, sizeof es, "MPI error %d", rc);
    return sooc_seterr(SOOC_EIO, "%s (%s) failed on rank %d of %d (%s): %s", call, what ? what : "?", g_rank, g_size,
                       g_host, es);
}

sooc_status sooc_dist_init(int *argc, char ***argv) {
    int n = launcher_size();
    if (!under_mpi_launcher()) {   /* one rank, MPI off */
        if (n > 1)
            return sooc_seterr(SOOC_EINVAL, "started as one of %d tasks without an MPI launcher's environment "
                                            "(under Slurm use srun --mpi=pmix, docs/cluster.md)", n);
        return SOOC_OK;
    }
    int provided = 0, rc = MPI_Init_thread(argc, argv, MPI_THREAD_FUNNELED, &provided);
    if (rc != MPI_SUCCESS) return sooc_seterr(SOOC_EIO, "MPI_Init_thread failed (error %d)", rc);
    g_started = 1;
    MPI_Comm_set_errhandler(MPI_COMM_WORLD, MPI_ERRORS_RETURN);
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    int len = 0;
    if (MPI_Get_processor_name(g_host, &len) != MPI_SUCCESS) snprintf(g_host, sizeof g_host, "?");
    if (g_size == 1 && n > 1)
        return sooc_seterr(SOOC_EINVAL, "the launcher started %d tasks but MPI sees a world of 1 "
                                        "(under Slurm use srun --mpi=pmix, docs/cluster.md)", n);
    return SOOC_OK;
}

void sooc_dist_finalize(void) {
    if (g_started) MPI_Finalize();
    g_started = 0;
}

void sooc_dist_abort(int code) {
    if (g_started) MPI_Abort(MPI_COMM_WORLD, code);
}

/* MPI counts are int: large buffers go in chunks. */
#define CHUNK ((size_t)1 << 30)

sooc_status sooc_dist_sum_f32(float *buf, size_t n, const char *what) {
    if (!g_started || g_size == 1) return SOOC_OK;
    for (size_t i = 0; i < n; i += CHUNK) {
        int c = (int)(n - i < CHUNK ? n - i : CHUNK);
        int rc = MPI_Allreduce(MPI_IN_PLACE, buf + i, c, MPI_FLOAT, MPI_SUM, MPI_COMM_WORLD);
        if (rc != MPI_SUCCESS) return mpi_fail(rc, "MPI_Allreduce", what);
    }
    return SOOC_OK;
}

sooc_status sooc_dist_sum_f64(double *buf, size_t n, const char *what) {
    if (!g_started || g_size == 1) return SOOC_OK;
    for (size_t i = 0; i < n; i += CHUNK) {
        int c = (int)(n - i < CHUNK ? n - i : CHUNK);
        int rc = MPI_Allreduce(MPI_IN_PLACE, buf + i, c, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
        if (rc != MPI_SUCCESS) return mpi_fail(rc, "MPI_Allreduce", what);
    }
    return SOOC_OK;
}

sooc_status sooc_dist_bcast(void *buf, size_t bytes, const char *what) {
    if (!g_started || g_size == 1) return SOOC_OK;
    for (size_t i = 0; i < bytes; i += CHUNK) {
        int c = (int)(bytes - i < CHUNK ? bytes - i : CHUNK);
        int rc = MPI_Bcast((char *)buf + i, c, MPI_BYTE, 0, MPI_COMM_WORLD);
        if (rc != MPI_SUCCESS) return mpi_fail(rc, "MPI_Bcast", what);
    }
    return SOOC_OK;
}

#else /* no MPI: a world of one */

int sooc_dist_compiled(void) { return 0; }

sooc_status sooc_dist_init(int *argc, char ***argv) {
    (void)argc, (void)argv;
    int n = launcher_size();
    if (n > 1)
        return sooc_seterr(SOOC_EINVAL, "started as one of %d MPI tasks, but this sooc3d was built without MPI "
                                        "(install libopenmpi-dev and rebuild with -DSOOC_WITH_MPI=ON)", n);
    return SOOC_OK;
}
void sooc_dist_finalize(void) {}
void sooc_dist_abort(int code) { (void)code; }
sooc_status sooc_dist_sum_f32(float *buf, size_t n, const char *what) {
    (void)buf, (void)n, (void)what;
    return SOOC_OK;
}
sooc_status sooc_dist_sum_f64(double *buf, size_t n, const char *what) {
    (void)buf, (void)n, (void)what;
    return SOOC_OK;
}
sooc_status sooc_dist_bcast(void *buf, size_t bytes, const char *what) {
    (void)buf, (void)bytes, (void)what;
    return SOOC_OK;
}

#endif
