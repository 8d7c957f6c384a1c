/* Torn-read stress: one writer process rewrites 16 records flat out, every
 * field derived from one counter (tt_make); two reader processes copy records
 * for ~2 s with sooc_table_read_record and count copies that are not
 * self-consistent. Zero torn copies may be accepted.
 *
 * NEGATIVE CONTROL: the same readers with the seqlock check removed (a
 * runtime switch in this test, not in the library: they copy the words with
 * relaxed loads and never compare seq). They must see torn copies, which shows
 * the consistency check can fail. If the window finds none, it is lengthened
 * (1, 2, 4 s).
 *
 * Env: SOOC_TABLE_STRESS_S overrides the validated phase length (seconds). */
#include "check.h"
#include "table_test_util.h"

#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/wait.h>

#define NREC 16

typedef struct {
    long long attempts, accepted, torn, gave_up;
} reader_stats;

static _Noreturn void writer_main(const char *name, int ready_fd) {
    sooc_table_writer *w = NULL;
    if (sooc_table_create_writer(name, NREC, 0, "map", &w) != 0) _exit(3);
    sooc_table_record rec;
    char c = 'R';
    for (uint32_t cnt = 1;; cnt++) {
        sooc_table_begin_batch(w);
        for (uint64_t k = 0; k < NREC; k++) {
            tt_make(&rec, 100 + k, cnt);
            sooc_table_upsert(w, &rec);
        }
        sooc_table_end_batch(w);
        sooc_table_heartbeat(w);
        if (cnt == 1 && write(ready_fd, &c, 1) != 1) _exit(4);
    }
}

/* Copy without any seqlock validation: the negative control. */
static void copy_unvalidated(const sooc_table_record *src, sooc_table_record *dst) {
    const _Atomic(uint64_t) *s = (const _Atomic(uint64_t) *)src;
    uint64_t w[32];
    for (int i = 0; i < 32; i++) w[i] = atomic_load_explicit(&s[i], memory_order_relaxed);
    memcpy((void *)dst, w, sizeof w);
}

static _Noreturn void reader_main(const char *name, int validate, double seconds, int out_fd) {
    sooc_table_reader *r = NULL;
    if (sooc_table_open_reader(name, &r) != 0) _exit(5);
    reader_stats st = {0, 0, 0, 0};
    const sooc_table_record *recs = NULL;
    int fd = -1;
    if (!validate) { /* map the records ourselves: the library never hands out torn data */
        char shm[128];
        sooc_table_shm_name(name, shm, sizeof shm);
        fd = shm_open(shm, O_RDONLY, 0);
        void *base = mmap(NULL, 4096 + NREC * 256, PROT_READ, MAP_SHARED, fd, 0);
        if (base == MAP_FAILED) _exit(6);
        recs = (const sooc_table_record *)((const char *)base + 4096);
    }
    int64_t end = tt_mono_ns() + (int64_t)(seconds * 1e9);
    sooc_table_record rec;
    while (tt_mono_ns() < end) {
        for (int rep = 0; rep < 64; rep++) {
            for (uint32_t k = 0; k < NREC; k++) {
                st.attempts++;
                if (validate) {
                    if (sooc_table_read_record(r, k, &rec) != 0) {
                        st.gave_up++;
                        continue;
                    }
                } else {
                    copy_unvalidated(&recs[k], &rec);
                }
                st.accepted++;
                if (!tt_consistent(&rec)) st.torn++;
            }
        }
    }
    if (write(out_fd, &st, sizeof st) != (ssize_t)sizeof st) _exit(7);
    _exit(0);
}

/* Run one phase: 2 reader processes for `seconds`; sums their stats. */
static int run_readers(const char *name, int validate, double seconds, reader_stats *sum,
                       reader_stats per[2]) {
    int fds[2][2];
    pid_t pids[2];
    memset(sum, 0, sizeof *sum);
    for (int i = 0; i < 2; i++) {
        if (pipe(fds[i]) != 0) return -1;
        pids[i] = fork();
        if (pids[i] == 0) {
            close(fds[i][0]);
            reader_main(name, validate, seconds, fds[i][1]);
        }
        close(fds[i][1]);
    }
    int ok = 0;
    for (int i = 0; i < 2; i++) {
        reader_stats st;
        if (read(fds[i][0], &st, sizeof st) == (ssize_t)sizeof st) {
            per[i] = st;
            sum->attempts += st.attempts;
            sum->accepted += st.accepted;
            sum->torn += st.torn;
            sum->gave_up += st.gave_up;
            ok++;
        }
        close(fds[i][0]);
        int status;
        waitpid(pids[i], &status, 0);
    }
    return ok == 2 ? 0 : -1;
}

int main(void) {
    char name[64];
    tt_name(name, sizeof name, "stress");
    double seconds = getenv("SOOC_TABLE_STRESS_S") ? atof(getenv("SOOC_TABLE_STRESS_S")) : 2.0;

    int ready[2];
    CHECK(pipe(ready) == 0);
    pid_t wpid = fork();
    if (wpid == 0) {
        close(ready[0]);
        writer_main(name, ready[1]);
    }
    close(ready[1]);
    char c = 0;
    CHECK_MSG(read(ready[0], &c, 1) == 1 && c == 'R', "writer did not start");
    close(ready[0]);

    reader_stats sum, per[2];
    CHECK(run_readers(name, 1, seconds, &sum, per) == 0);
    for (int i = 0; i < 2; i++)
        printf("validated reader %d: %lld attempts, %lld accepted, %lld torn accepted, "
               "%lld gave up after %d retries\n",
               i, per[i].attempts, per[i].accepted, per[i].torn, per[i].gave_up,
               SOOC_TABLE_READ_RETRIES);
    CHECK_MSG(sum.torn == 0, "%lld torn records accepted with validation", sum.torn);
    CHECK_MSG(per[0].accepted > 10000 && per[1].accepted > 10000, "too few reads: %lld %lld",
              per[0].accepted, per[1].accepted);

    /* negative control: must detect torn copies, else the test could not fail */
    reader_stats ctl = {0, 0, 0, 0};
    double tried = 0;
    for (double s = 1.0; s <= 4.0 && ctl.torn == 0; s *= 2) {
        CHECK(run_readers(name, 0, s, &ctl, per) == 0);
        tried += s;
        printf("negative control (no validation, %.0f s): %lld copies, %lld torn\n", s,
               ctl.accepted, ctl.torn);
    }
    CHECK_MSG(ctl.torn > 0, "negative control found no torn reads in %.0f s", tried);

    kill(wpid, SIGKILL);
    waitpid(wpid, NULL, 0);
    char shm[128];
    sooc_table_shm_name(name, shm, sizeof shm);
    shm_unlink(shm);
    printf("{\"validated_reads\":%lld,\"torn_accepted\":%lld,\"gave_up\":%lld,"
           "\"control_torn\":%lld}\n",
           sum.accepted, sum.torn, sum.gave_up, ctl.torn);
    return check_report("test_table_stress");
}
