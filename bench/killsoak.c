/* killsoak.c - the kill -9 soak of sessions (issue 8): N seeded runs, each a fresh goniod and
 * gonio-sim (--time-scale 10, the e2e rig) running a session of 288 captures
 * (bench_session: some seconds, so that most kills land in it), killed with SIGKILL 1 to 3
 * times at random moments (session_run_killing: 0.1-1.3 s apart): goniod, gonio-sim or
 * both, each time resumed with session.resume until the session ends; then the dataset
 * must hold every planned capture exactly once, rows matching what gonio-sim rendered, and
 * ds_check must find nothing wrong (check_complete, as tests/e2e/test-session.c's kill
 * cases, with 2 kills of one kind). Each run is a child process in its own process group: a
 * failed check fails the run, not the soak, and a run stuck for RUN_TIMEOUT_S is killed
 * with its goniod and gonio-sim. A failed run keeps its directory (goniod's log in it).
 * Options: --runs N (30), --seed S (1: run i uses seed S + i).
 * Last line: {"bench":"killsoak","runs":N,"failures":F,"kills":K,"kills_daemon":..,
 * "kills_sim":..,"kills_both":..,"seconds":..}. */
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>
#include <unistd.h>

#include "bench.h"
#include "tests/test.h"

#define TIME_SCALE    10
#define RUN_TIMEOUT_S 300
#define MAX_KILLS     3

static const char *const victims[] = {"d", "s", "ds"}; /* goniod, gonio-sim, both */

/* One run's kills, drawn from its seed. */
struct plan {
        unsigned seed;
        int kills;
        int who[MAX_KILLS]; /* index into victims */
};

static struct plan draw(unsigned seed)
{
        struct plan p = {.seed = seed};

        srand(seed);
        p.kills = 1 + rand() % MAX_KILLS;
        for (int k = 0; k < p.kills; k++)
                p.who[k] = rand() % 3;
        return p;
}

/* The child: runs the session with p's kills and checks it. Exits 0 when complete. */
static void run_child(const struct plan *p)
{
        const char *who[MAX_KILLS];
        struct rigenv e;
        char file[400];
        int64_t n;

        for (int k = 0; k < p->kills; k++)
                who[k] = victims[p->who[k]];
        bench_start(&e, TIME_SCALE, true);
        printf("  seed %u: %s\n", p->seed, e.dir);
        fflush(stdout);
        srand(p->seed * 7919u + 1); /* the moments of the kills */
        bench_session(&e, "soak", false, file, sizeof(file));
        n = sess_planned(&e, file, NULL);
        sess_run_killing(&e, file, who, p->kills);
        sess_check_complete(&e, "soak", "soak", n);
        rigenv_stop(&e);
        exit(0);
}

/* Runs p in a child; returns whether it passed. */
static bool run(const struct plan *p)
{
        pid_t pid;
        int status = 0;

        fflush(stdout);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                setpgid(0, 0);
                run_child(p);
        }
        for (int t = 0; t < RUN_TIMEOUT_S * 10; t++) {
                if (waitpid(pid, &status, WNOHANG) == pid)
                        return WIFEXITED(status) && WEXITSTATUS(status) == 0;
                usleep(100000);
        }
        printf("  seed %u: no end within %d s, killed\n", p->seed, RUN_TIMEOUT_S);
        kill(-pid, SIGKILL); /* the run with its goniod, gonio-sim and gonioctl */
        waitpid(pid, &status, 0);
        return false;
}

int main(int argc, char **argv)
{
        static const struct option opts[] = {
                {"runs", required_argument, NULL, 'r'}, {"seed", required_argument, NULL, 's'}, {}};
        int runs = 30, seed = 1, c, failures = 0, kills[3] = {0};
        double t0 = bench_now_ms();

        while ((c = getopt_long(argc, argv, "r:s:", opts, NULL)) >= 0) {
                CHECK(c == 'r' || c == 's');
                *(c == 'r' ? &runs : &seed) = atoi(optarg);
        }
        CHECK(runs > 0);
        for (int i = 0; i < runs; i++) {
                struct plan p = draw((unsigned)(seed + i));
                bool ok;

                printf("run %d (seed %u): kill", i + 1, p.seed);
                for (int k = 0; k < p.kills; k++) {
                        printf(" %s", (const char *[]){"goniod", "gonio-sim", "both"}[p.who[k]]);
                        kills[p.who[k]]++;
                }
                printf("\n");
                ok = run(&p);
                failures += !ok;
                printf("run %d (seed %u): %s\n", i + 1, p.seed,
                       ok ? "complete, exactly once" : "FAILED");
        }
        printf("%d runs, %d failed, %d kills (goniod %d, gonio-sim %d, both %d), %.0f s\n", runs,
               failures, kills[0] + kills[1] + kills[2], kills[0], kills[1], kills[2],
               (bench_now_ms() - t0) / 1e3);
        printf("{\"bench\":\"killsoak\",\"runs\":%d,\"failures\":%d,\"kills\":%d,\"kills_daemon\":%"
               "d,"
               "\"kills_sim\":%d,\"kills_both\":%d,\"seconds\":%.0f}\n",
               runs, failures, kills[0] + kills[1] + kills[2], kills[0], kills[1], kills[2],
               (bench_now_ms() - t0) / 1e3);
        return 0;
}
