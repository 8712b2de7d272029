/* latency.c - goniod's answers while a session runs at full speed, against an idle goniod
 * in the same run: `status` round trips (p50, p99 of >= 1000 samples, one client sending
 * status in a loop over a raw socket, 2 ms apart) and `stop` sent while an axis moves until
 * gonio-sim's drive halts (its angle polled over gonio-sim's control socket, each sample
 * the first poll that saw the final angle; a sample whose axis ended on its target is
 * discarded, as the move may have ended by itself). A stop pauses the session: it is
 * resumed, once status says the rig is idle, before the next sample. gonio-sim runs at
 * --time-scale 20 on the e2e test rig: sessions go as fast as goniod moves, exposes,
 * renders and stores (about 67 captures/s of 288).
 * Targets (issue 8): status p99 < 5 ms, stop to halt < 20 ms.
 * Last line: {"bench":"latency","status_p50_ms":..,"status_p99_ms":..,"stop_to_halt_ms":..
 * (median), "stop_to_halt_max_ms", "stop_rtt_p50_ms", "idle_*" the same without a session,
 * "status_samples", "stop_samples", "session_captures_per_s"}. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "common/pose.h"
#include "tests/test.h"

#define TIME_SCALE     20
#define STATUS_SAMPLES 1000 /* at least, per condition */
#define STATUS_GAP_US  2000
#define STOP_SAMPLES   30
#define HALT_QUIET_MS  10.0 /* an angle unchanged this long has halted */

static const char status_req[] = "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"status\"}\n";

/* What one condition measured. */
struct lat {
        struct bench_samples status, stop_rtt, halt;
        unsigned discarded; /* stop samples where the move ended by itself */
};

/* One status round trip on fd, in ms. */
static double status_rtt(int fd)
{
        double t0 = bench_now_ms();
        json_t *r = raw_call(fd, status_req);

        CHECK(json_object_get(r, "result"));
        json_decref(r);
        return bench_now_ms() - t0;
}

/* Whether a session is active, by session.status on fd (not timed); its capture rate so
 * far into *rate while it runs (rate may be NULL). */
static bool session_running(int fd, double *rate)
{
        json_t *r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":2,\"method\":\"session.status\"}\n");
        json_t *st = json_object_get(r, "result");
        const char *state = json_string_value(json_object_get(st, "state"));
        bool running = state && strcmp(state, "none") != 0;

        if (rate && state && strcmp(state, "running") == 0)
                *rate = json_number_value(json_object_get(st, "rate_per_s"));
        json_decref(r);
        return running;
}

/* Samples status every STATUS_GAP_US until the session on the rig ends (with session, its
 * capture rate into *rate) or for STATUS_SAMPLES samples (without: rate NULL). */
static void sample_status(int fd, double *rate, struct bench_samples *out)
{
        for (size_t i = 0;; i++) {
                if (rate ? i % 50 == 0 && !session_running(fd, rate) : i == STATUS_SAMPLES)
                        return;
                bench_add(out, status_rtt(fd));
                usleep(STATUS_GAP_US);
        }
}

/* Waits (up to 5 s) until an axis moves in gonio-sim; returns its role, or -1. */
static int wait_motion(struct rigenv *e, int *simfd, double deg[GN_ROLE_COUNT])
{
        for (int r = 0; r < GN_ROLE_COUNT; r++)
                deg[r] = bench_sim_angle(e, simfd, r);
        for (double end = bench_now_ms() + 5000; bench_now_ms() < end; usleep(100))
                for (int r = 0; r < GN_ROLE_COUNT; r++) {
                        double a = bench_sim_angle(e, simfd, r);
                        if (a != deg[r])
                                return deg[r] = a, r;
                }
        return -1;
}

/* Polls role's angle until it has not changed for HALT_QUIET_MS; returns the time of the
 * first poll that saw the final angle, in ms, and that angle in *final. */
static double wait_halt(struct rigenv *e, int *simfd, int role, double *final)
{
        double last = bench_sim_angle(e, simfd, role), t_final = bench_now_ms();

        for (;;) {
                double a = bench_sim_angle(e, simfd, role), t = bench_now_ms();
                if (a != last)
                        last = a, t_final = t;
                else if (t - t_final > HALT_QUIET_MS)
                        return *final = last, t_final;
        }
}

/* Whether deg is (modulo 360) one of the targets of the moves stopped: 0 or 180. */
static bool at_target(double deg)
{
        double m = fmod(fabs(deg), 180);

        return m < 0.01 || m > 179.99;
}

/* One stop sample: waits for a move, lets it run 5-40 ms, checks that it still moves, sends
 * stop and measures until the drive halts. A sample is kept only when the axis halted
 * short of its target (else the move may have ended by itself). Returns 1 when it sent
 * stop, 0 when the move had ended before, -1 when no axis moved within 5 s. */
static int sample_stop(struct rigenv *e, int fd, int *simfd, struct lat *l)
{
        double deg[GN_ROLE_COUNT], before, t0, t_halt, final;
        int role = wait_motion(e, simfd, deg);
        json_t *r;

        if (role < 0)
                return -1;
        usleep(5000 + rand() % 35000);
        before = bench_sim_angle(e, simfd, role);
        if (bench_sim_angle(e, simfd, role) == before)
                return l->discarded++, 0; /* it ended already */
        t0 = bench_now_ms();
        r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":3,\"method\":\"stop\"}\n");
        bench_add(&l->stop_rtt, bench_now_ms() - t0);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        t_halt = wait_halt(e, simfd, role, &final);
        if (at_target(final))
                l->discarded++;
        else
                bench_add(&l->halt, t_halt - t0);
        return 1;
}

/* Idle reference: moves the turntable 180 deg back and forth and stops each move. */
static void idle_stops(struct rigenv *e, int fd, int *simfd, struct lat *l)
{
        json_decref(ctl_ok(e, "home", NULL));
        for (int i = 0; l->halt.n < STOP_SAMPLES; i++) {
                char req[160];
                json_t *r;

                snprintf(req, sizeof(req),
                         "{\"jsonrpc\":\"2.0\",\"id\":4,\"method\":\"move\",\"params\":"
                         "{\"axis\":\"turntable\",\"position\":%d,\"wait\":false}}\n",
                         i % 2 ? 0 : 180);
                r = raw_call(fd, req);
                CHECK(json_object_get(r, "result"));
                json_decref(r);
                CHECK(sample_stop(e, fd, simfd, l) >= 0);
                usleep(100000);
        }
}

/* Waits until status on fd says the rig is idle: a session paused by stop is paused before
 * its axes have stopped (goniod follows them until they stand still), and a resume then
 * finds an axis "stopping" and pauses again at once. */
static void wait_rig_idle(int fd)
{
        for (double end = bench_now_ms() + 5000;; usleep(1000)) {
                json_t *r = raw_call(fd, status_req);
                const char *st =
                        json_string_value(json_object_get(json_object_get(r, "result"), "state"));
                bool idle = st && strcmp(st, "idle") == 0;

                json_decref(r);
                if (idle)
                        return;
                CHECK(bench_now_ms() < end);
        }
}

/* Stops the moves of sessions of big moves, resuming each after its pause, until
 * STOP_SAMPLES samples; starts a new session when one ends. */
static void session_stops(struct rigenv *e, int fd, int *simfd, struct lat *l)
{
        char file[400], name[32];
        int k = 0, r = 0;

        while (l->halt.n < STOP_SAMPLES) {
                snprintf(name, sizeof(name), "stop%d", k++);
                close(sess_start_raw(e, bench_session(e, name, true, file, sizeof(file))));
                while (l->halt.n < STOP_SAMPLES && (r = sample_stop(e, fd, simfd, l)) >= 0) {
                        if (r == 0)
                                continue;
                        sess_wait(e, "paused", 10);
                        wait_rig_idle(fd);
                        json_decref(raw_call(
                                fd,
                                "{\"jsonrpc\":\"2.0\",\"id\":5,\"method\":\"session.resume\"}\n"));
                }
                json_decref(raw_call(
                        fd, "{\"jsonrpc\":\"2.0\",\"id\":6,\"method\":\"session.abort\"}\n"));
                while (session_running(fd, NULL))
                        usleep(20000);
        }
}

static void print_lat(const char *what, struct lat *l)
{
        printf("%s: status p50 %.3f ms, p99 %.3f ms, max %.3f ms (%zu samples); stop answered "
               "p50 %.3f ms; stop to halt p50 %.2f ms, max %.2f ms (%zu samples, %u discarded: the "
               "move had ended)\n",
               what, bench_quantile(&l->status, 0.5), bench_quantile(&l->status, 0.99),
               bench_quantile(&l->status, 1), l->status.n, bench_quantile(&l->stop_rtt, 0.5),
               bench_quantile(&l->halt, 0.5), bench_quantile(&l->halt, 1), l->halt.n, l->discarded);
}

int main(void)
{
        struct lat idle = {0}, busy = {0};
        struct rigenv e;
        char file[400], name[32];
        int fd, simfd = -1;
        double rate = 0;

        srand(8);
        bench_start(&e, TIME_SCALE, false);
        fd = bench_client(&e, "bench-latency");
        sample_status(fd, NULL, &idle.status);
        idle_stops(&e, fd, &simfd, &idle);
        for (int k = 0; busy.status.n < STATUS_SAMPLES; k++) {
                snprintf(name, sizeof(name), "lat%d", k);
                close(sess_start_raw(&e, bench_session(&e, name, false, file, sizeof(file))));
                sample_status(fd, &rate, &busy.status);
                printf("session %s: %.1f captures/s while status was sampled\n", name, rate);
        }
        session_stops(&e, fd, &simfd, &busy);
        close(simfd);
        close(fd);
        rigenv_stop(&e);
        print_lat("idle", &idle);
        print_lat("session running", &busy);
        printf("{\"bench\":\"latency\",\"status_p50_ms\":%.3f,\"status_p99_ms\":%.3f,"
               "\"stop_to_halt_ms\":%.2f,\"stop_to_halt_max_ms\":%.2f,\"stop_rtt_p50_ms\":%.3f,"
               "\"idle_status_p50_ms\":%.3f,\"idle_status_p99_ms\":%.3f,"
               "\"idle_stop_to_halt_ms\":%.2f,\"idle_stop_to_halt_max_ms\":%.2f,"
               "\"idle_stop_rtt_p50_ms\":%.3f,\"status_samples\":%zu,\"stop_samples\":%zu,"
               "\"session_captures_per_s\":%.1f}\n",
               bench_quantile(&busy.status, 0.5), bench_quantile(&busy.status, 0.99),
               bench_quantile(&busy.halt, 0.5), bench_quantile(&busy.halt, 1),
               bench_quantile(&busy.stop_rtt, 0.5), bench_quantile(&idle.status, 0.5),
               bench_quantile(&idle.status, 0.99), bench_quantile(&idle.halt, 0.5),
               bench_quantile(&idle.halt, 1), bench_quantile(&idle.stop_rtt, 0.5), busy.status.n,
               busy.halt.n, rate);
        return 0;
}
