/*
 * Data-parallel training over MPI (docs/cluster.md).
 *
 * `mpirun -np N sooc3d train ...` runs N ranks. Every rank holds the whole
 * model; each takes a disjoint share of a step's scenes, and the gradients
 * are summed with one in-place allreduce over the flat gradient slab, so
 * every rank applies the same Adam update. Rank 0 alone writes checkpoints,
 * logs, validation and curves (src/train/trainer.c).
 *
 * This is the whole interface; the MPI calls live in src/train/dist.c.
 * Without MPI (built with -DSOOC_WITH_MPI=OFF, or Open MPI absent) or when
 * the process was not started by an MPI launcher (no OMPI_COMM_WORLD_SIZE,
 * PMIX_RANK or PMI_RANK in the environment), it is one rank of one and every
 * collective is a no-op. A build without MPI that finds itself started as one
 * of several ranks refuses to run (sooc_dist_init fails) rather than let N
 * copies write the same files.
 *
 * Errors: MPI_COMM_WORLD gets MPI_ERRORS_RETURN, every call is checked, and a
 * failing collective returns SOOC_EIO with a message naming this rank, the
 * call and MPI's error string. The caller (the CLI) then calls
 * sooc_dist_abort so that no other rank waits forever. A rank that dies
 * (signal, exit without finalising) is caught by the runtime: mpirun aborts
 * the job and names the rank ("mpirun noticed that process rank R ...").
 * The library never prints or exits; sooc_dist_abort is for the CLI only.
 *
 * Contract (CONTRIBUTING.md "Coding rules") where this header does not say
 * otherwise. Ownership: the caller owns what it creates and releases it with
 * the matching _destroy / _free / _close (NULL-safe); pointers a getter
 * returns are borrowed and live as long as their object. Threads: an object
 * is used by one thread at a time; functions without an object are
 * reentrant. Errors: a status other than SOOC_OK comes with a message naming
 * the file, key or line (sooc_errmsg); nothing here prints or exits.
 */
#ifndef SOOC3D_DIST_H
#define SOOC3D_DIST_H

#include <stddef.h>

#include "sooc3d/core.h"

#ifdef __cplusplus
extern "C" {
#endif

/* 1 if this build has MPI (SOOC_WITH_MPI and Open MPI found). */
int sooc_dist_compiled(void);
/* Start MPI if the process was started by an MPI launcher; otherwise (or
 * without MPI) become rank 0 of 1. argc/argv may be NULL. Call once, before
 * any other sooc_dist_* call. */
sooc_status sooc_dist_init(int *argc, char ***argv);
/* Finalise MPI if sooc_dist_init started it. */
void sooc_dist_finalize(void);
/* Abort every rank of the job (MPI_Abort) with exit code `code`; without MPI
 * it returns (the caller exits). For the CLI's failure path. */
void sooc_dist_abort(int code);

int sooc_dist_rank(void);   /* 0 .. size-1 (0 without MPI)           */
int sooc_dist_size(void);   /* number of ranks (1 without MPI)       */
/* Processor name (host) of this rank, for messages. */
const char *sooc_dist_host(void);

/* In-place sums over all ranks (MPI_Allreduce with MPI_IN_PLACE, MPI_SUM).
 * `what` names the collective in an error message. */
sooc_status sooc_dist_sum_f32(float *buf, size_t n, const char *what);
sooc_status sooc_dist_sum_f64(double *buf, size_t n, const char *what);
/* Rank 0's bytes to every rank (MPI_Bcast). */
sooc_status sooc_dist_bcast(void *buf, size_t bytes, const char *what);

#ifdef __cplusplus
}
#endif
#endif /* SOOC3D_DIST_H */
