/* Dead and hung writers, and restart after a crash.
 *  1. A writer child killed with SIGKILL is seen as dead by a reader within
 *     1 s (flock released by the kernel); the detection time is printed.
 *  2. A stopped (SIGSTOP) writer is seen as hung once its heartbeat is older
 *     than SOOC_TABLE_HEARTBEAT_STALE_NS, and alive again after SIGCONT.
 *  3. A writer killed mid-batch, with one record left odd (the test pokes the
 *     seq the way a crash inside a record write leaves it): readers get EBUSY,
 *     never torn data; a restarted writer makes every seq even again, drops
 *     the torn record, keeps the others and renews the instance id. */
#include "check.h"
#include "table_test_util.h"

#include <fcntl.h>
#include <signal.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <sys/mman.h>
#include <sys/wait.h>

/* Fork a writer that publishes objects 1..5, signals `ready`, then either
 * keeps publishing (mode 0) or opens a batch, updates id 2, adds id 6, leaves
 * slot 2 (id 3) odd and waits (mode 1). */
static pid_t spawn_writer(const char *name, int mode) {
    int p[2];
    if (pipe(p) != 0) return -1;
    pid_t pid = fork();
    if (pid != 0) {
        close(p[1]);
        char c = 0;
        if (read(p[0], &c, 1) != 1 || c != 'R') {
            close(p[0]);
            return -1;
        }
        close(p[0]);
        return pid;
    }
    close(p[0]);
    sooc_table_writer *w = NULL;
    if (sooc_table_create_writer(name, 16, 0, "map", &w) != 0) _exit(3);
    if (sooc_table_start_heartbeat(w, 20) != 0) _exit(4);
    sooc_table_record rec;
    sooc_table_begin_batch(w);
    for (uint64_t id = 1; id <= 5; id++) {
        tt_make(&rec, id, (uint32_t)id);
        sooc_table_upsert(w, &rec);
    }
    sooc_table_end_batch(w);
    if (mode == 1) {
        sooc_table_begin_batch(w);
        tt_make(&rec, 2, 200);
        sooc_table_upsert(w, &rec);
        tt_make(&rec, 6, 6);
        sooc_table_upsert(w, &rec);
        /* simulate dying inside the write of slot 2: seq odd, payload half new */
        char shm[128];
        sooc_table_shm_name(name, shm, sizeof shm);
        int fd = shm_open(shm, O_RDWR, 0);
        char *base = mmap(NULL, 4096 + 16 * 256, PROT_READ | PROT_WRITE, MAP_SHARED, fd, 0);
        if (base == MAP_FAILED) _exit(5);
        sooc_table_record *r2 = (sooc_table_record *)(base + 4096 + 2 * 256);
        atomic_fetch_add(&r2->seq, 1);
        r2->x = -1e9f;
    }
    char c = 'R';
    if (write(p[1], &c, 1) != 1) _exit(6);
    for (uint32_t cnt = 10;; cnt++) {
        if (mode == 0) {
            sooc_table_begin_batch(w);
            tt_make(&rec, 1, cnt);
            sooc_table_upsert(w, &rec);
            sooc_table_end_batch(w);
        }
        tt_sleep_ms(2);
    }
}

static void cleanup(const char *name) {
    char shm[128];
    sooc_table_shm_name(name, shm, sizeof shm);
    shm_unlink(shm);
}

static void test_kill_detect(void) {
    char name[64];
    tt_name(name, sizeof name, "kill");
    pid_t pid = spawn_writer(name, 0);
    CHECK(pid > 0);
    if (pid <= 0) return;
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(name, &r) == 0);
    if (!r) return;
    sooc_table_liveness live;
    CHECK(sooc_table_writer_alive(r, &live) == 1 && live.writer_pid == pid);

    /* hung: SIGSTOP freezes the heartbeat thread too */
    kill(pid, SIGSTOP);
    int64_t t0 = tt_mono_ns(), t_hung = -1;
    while (tt_mono_ns() - t0 < 3000000000ll) {
        if (sooc_table_writer_alive(r, &live) == 0) {
            t_hung = tt_mono_ns() - t0;
            break;
        }
        tt_sleep_ms(5);
    }
    CHECK_MSG(t_hung > 0 && live.lock_held && !live.exited, "hung writer not detected");
    printf("stopped writer reported hung after %.0f ms (stale threshold %lld ms)\n", t_hung * 1e-6,
           SOOC_TABLE_HEARTBEAT_STALE_NS / 1000000);
    kill(pid, SIGCONT);
    tt_sleep_ms(150);
    CHECK(sooc_table_writer_alive(r, &live) == 1);

    /* dead: SIGKILL; do not reap first, so only the kernel's cleanup counts */
    t0 = tt_mono_ns();
    kill(pid, SIGKILL);
    int64_t t_dead = -1;
    while (tt_mono_ns() - t0 < 2000000000ll) {
        if (sooc_table_writer_alive(r, &live) == 0) {
            t_dead = tt_mono_ns() - t0;
            break;
        }
        tt_sleep_ms(1);
    }
    CHECK_MSG(t_dead >= 0 && t_dead < 1000000000ll, "dead writer detected after %lld ns",
              (long long)t_dead);
    CHECK(!live.lock_held && !live.exited);
    printf("SIGKILLed writer detected dead after %.3f ms\n", t_dead * 1e-6);
    waitpid(pid, NULL, 0);
    sooc_table_close_reader(r);
    cleanup(name);
}

static void test_restart(void) {
    char name[64];
    tt_name(name, sizeof name, "restart");
    pid_t pid = spawn_writer(name, 1);
    CHECK(pid > 0);
    if (pid <= 0) return;
    sooc_table_reader *r = NULL;
    CHECK(sooc_table_open_reader(name, &r) == 0);
    if (!r) return;
    sooc_table_record out[16], rec;
    uint32_t n = 0;
    uint64_t epoch = 0;
    sooc_table_info info;
    CHECK(sooc_table_get_info(r, &info) == SOOC_TABLE_EBUSY); /* batch left open */
    uint64_t inst0 = 0;
    sooc_table_liveness live;
    CHECK(sooc_table_writer_alive(r, &live) == 1);
    inst0 = live.instance_id;
    kill(pid, SIGKILL);
    waitpid(pid, NULL, 0);
    CHECK(sooc_table_writer_alive(r, &live) == 0 && !live.lock_held);
    /* table_seq stays odd for good: bounded retries, then EBUSY */
    int64_t t0 = tt_mono_ns();
    CHECK(sooc_table_snapshot(r, out, 16, &n, &epoch) == SOOC_TABLE_EBUSY);
    printf("snapshot on a dead mid-batch table gave up after %.1f ms\n",
           (tt_mono_ns() - t0) * 1e-6);
    CHECK(sooc_table_read_record(r, 2, &rec) == SOOC_TABLE_EBUSY); /* torn, never returned */
    CHECK(sooc_table_read_record(r, 1, &rec) == 0 && rec.obs_count == 200 && tt_consistent(&rec));

    /* restart */
    sooc_table_writer *w = NULL;
    CHECK(sooc_table_create_writer(name, 16, 0, "map", &w) == 0);
    if (!w) return;
    CHECK(sooc_table_writer_alive(r, &live) == 1 && live.instance_id != inst0);
    CHECK(live.writer_pid == getpid());
    CHECK(sooc_table_snapshot(r, out, 16, &n, &epoch) == 0);
    CHECK_MSG(n == 5, "n = %u", n);
    uint64_t seen = 0;
    for (uint32_t i = 0; i < n; i++) {
        CHECK((out[i].seq & 1) == 0 && tt_consistent(&out[i]));
        seen |= 1ull << out[i].object_id;
    }
    CHECK_MSG(seen == ((1ull << 1) | (1ull << 2) | (1ull << 4) | (1ull << 5) | (1ull << 6)),
              "ids seen %llx", (unsigned long long)seen);
    for (uint32_t s = 0; s < 16; s++) {
        CHECK(sooc_table_read_record(r, s, &rec) == 0); /* every seq even again */
    }
    CHECK(sooc_table_get_info(r, &info) == 0 && info.n_objects == 5);
    CHECK(sooc_table_writer_count(w) == 5);
    /* the writer keeps working: id 3 comes back into the freed slot, 2 updates in place */
    CHECK(sooc_table_begin_batch(w) == 0);
    tt_make(&rec, 3, 33);
    CHECK(sooc_table_upsert(w, &rec) == 0);
    tt_make(&rec, 2, 22);
    CHECK(sooc_table_upsert(w, &rec) == 0);
    CHECK(sooc_table_end_batch(w) == 0);
    CHECK(sooc_table_read_record(r, 2, &rec) == 0 && rec.object_id == 3 && rec.obs_count == 33);
    CHECK(sooc_table_find(r, 2, &rec) == 0 && rec.obs_count == 22);
    CHECK(sooc_table_snapshot(r, out, 16, &n, &epoch) == 0 && n == 6);
    CHECK(sooc_table_close_writer(w, 1) == 0);
    sooc_table_close_reader(r);
}

int main(void) {
    test_kill_detect();
    test_restart();
    return check_report("test_table_crash");
}
