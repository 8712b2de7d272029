/* soak.c - the reliability soak of issue 13: one session of 10,080 captures on the e2e rig
 * (gonio-sim at --time-scale 20: 360 turntable x 7 light-arm positions x 2 lamps x 2
 * cameras) watched by 100 clients, with faults injected at random moments 1 to 3 s apart:
 * a drive that stops answering, relay replies with bad CRCs, a camera frame dropped; once
 * goniod killed with SIGKILL (after a tenth of the captures) and once the data disk full
 * (after half: the tmpfs under the data root shrunk to what it holds). After each, the bench
 * does what an operator would: clears the injected fault, `fault clear`, `session resume`.
 * At the end every planned capture must be there exactly once, rows matching what gonio-sim
 * rendered (sess_check_complete: dataset check clean), and goniod's resident set is reported
 * after the first thousand captures of its last start and at the end. Needs root for the
 * tmpfs (else no disk-full fault, said). Options: --seed S (1), --captures-scale F (1: the
 * full session; 0.1 for a short run: fewer turntable positions). Last line:
 * {"bench":"soak","captures":..,"faults":..,"kills":..,"lost":0,"duplicated":0,
 * "rss_start_mb":..,"rss_end_mb":..}. */
#include <errno.h>
#include <getopt.h>
#include <sched.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <unistd.h>

#include "bench.h"
#include "dataset/ds.h"
#include "tests/test.h"

#define TIME_SCALE 20
#define WATCHERS   100
#define STALL_S    60 /* running without a capture this long: stalled */

struct soak {
        struct rigenv e;
        struct bench_watchers w;
        char file[400];
        int64_t planned;
        int faults, kills, rig_faults;
        bool killed, filled, tmpfs;
        double rss_start, rss_end;
};

/* goniod's resident set in MB (/proc). */
static double goniod_rss_mb(struct soak *s)
{
        char path[64], line[256];
        double kb = 0;
        FILE *f;

        snprintf(path, sizeof(path), "/proc/%d/status", (int)s->e.daemon);
        if (!(f = fopen(path, "re")))
                return 0;
        while (fgets(line, sizeof(line), f))
                if (sscanf(line, "VmRSS: %lf kB", &kb) == 1)
                        break;
        fclose(f);
        return kb / 1024;
}

/* The session's captures so far and its state into state. */
static int64_t progress(struct soak *s, char *state, size_t len)
{
        json_t *st = ctl_ok(&s->e, "session", "status", NULL);
        int64_t n = json_integer_value(json_object_get(st, "captured"));

        snprintf(state, len, "%s", json_string_value(json_object_get(st, "state")) ?: "none");
        json_decref(st);
        return n;
}

/* Fault kind (0: drive `unit` stops answering, 1: relay CRCs, 2: camera `unit` drops a frame)
 * on or cleared. */
static void inject(struct soak *s, int kind, int unit, bool on)
{
        char req[200];

        if (kind == 0)
                snprintf(req, sizeof(req),
                         "{\"cmd\":\"inject\",\"bus\":\"drives\",\"unit\":%d,\"fault\":\"%s\"}\n",
                         1 + unit, on ? "timeout" : "none");
        else if (kind == 1)
                snprintf(req, sizeof(req),
                         "{\"cmd\":\"inject\",\"bus\":\"relays\",\"unit\":10,\"fault\":\"%s\"}\n",
                         on ? "crc" : "none");
        else
                snprintf(req, sizeof(req),
                         "{\"cmd\":\"inject\",\"camera\":\"cam%d\",\"fault\":\"%s\",\"count\":1}\n",
                         unit, on ? "drop" : "none");
        sim_request(&s->e, req);
}

/* session.resume over a connection of its own, answered at once (gonioctl session resume
 * follows the session to its end); whether it was taken. */
static bool resume(struct soak *s)
{
        int fd = raw_connect(&s->e);
        json_t *r = raw_call(fd, "{\"jsonrpc\":\"2.0\",\"id\":1,\"method\":\"session.resume\"}\n");
        bool ok = json_object_get(r, "result") != NULL;

        json_decref(r);
        close(fd);
        return ok;
}

/* What an operator does after a fault: the cause gone, fault clear, session resume. */
static void recover(struct soak *s)
{
        char state[32];

        for (double end = now_s() + 30; now_s() < end; usleep(100000)) {
                json_t *st = ctl_ok(&s->e, "status", NULL);
                bool fault =
                        !strcmp(json_string_value(json_object_get(st, "state")) ?: "", "fault");
                json_decref(st);
                if (fault && ctl(&s->e, NULL, "fault", "clear", NULL) != 0)
                        continue;
                s->rig_faults += fault;
                progress(s, state, sizeof(state));
                if (!strcmp(state, "paused") && !resume(s))
                        continue;
                if (strcmp(state, "paused"))
                        return;
        }
        CHECK(!"the session did not resume within 30 s");
}

/* A random device fault, on for 1 to 2 s (a camera drop is one frame). */
static void device_fault(struct soak *s)
{
        int kind = rand() % 3, unit = rand() % 2;

        inject(s, kind, unit, true);
        usleep(1000000 + rand() % 1000000);
        inject(s, kind, unit, false);
        s->faults++;
        recover(s);
}

static void kill_goniod(struct soak *s)
{
        bench_watchers_stop(&s->w);
        rigenv_crash_daemon(&s->e);
        bench_watchers_start(&s->w, &s->e, WATCHERS);
        s->kills++;
        s->killed = true;
        s->rss_start = 0;
        CHECK(resume(s));
}

/* Whether goniod faults on the dataset (the store that found the disk full) within timeout
 * seconds. */
static bool dataset_fault(struct soak *s, double timeout)
{
        for (double end = now_s() + timeout; now_s() < end; usleep(100000)) {
                json_t *st = ctl_ok(&s->e, "status", NULL);
                const char *dev =
                        json_string_value(json_object_get(json_object_get(st, "fault"), "device"));
                bool f = dev && !strcmp(dev, "dataset");
                json_decref(st);
                if (f)
                        return true;
        }
        return false;
}

/* Shrinks the tmpfs at dir to what it holds. goniod may store more between the reading and
 * the remount (then EINVAL): read again. Returns 0 or -errno. */
static int shrink_to_used(const char *dir)
{
        for (int i = 0; i < 100; i++) {
                struct statvfs v;
                char opts[64];

                if (statvfs(dir, &v) < 0)
                        return -errno;
                snprintf(opts, sizeof(opts), "size=%llu",
                         (unsigned long long)(v.f_blocks - v.f_bfree) * v.f_frsize);
                if (mount(NULL, dir, NULL, MS_REMOUNT, opts) == 0)
                        return 0;
                if (errno != EINVAL)
                        return -errno;
        }
        return -EBUSY;
}

/* The data tmpfs shrunk to what it holds: the next store fails (ENOSPC) and goniod faults;
 * then room again. */
static void fill_disk(struct soak *s)
{
        s->filled = true;
        if (!s->tmpfs)
                return;
        CHECK_INT(shrink_to_used(s->e.data), 0);
        CHECK(dataset_fault(s, 20));
        CHECK(mount(NULL, s->e.data, NULL, MS_REMOUNT, "size=4g") == 0);
        s->faults++;
        recover(s);
}

static void setup(struct soak *s, double scale)
{
        char text[1024];
        int steps = (int)(360 * scale) < 2 ? 2 : (int)(360 * scale);

        /* in a mount namespace of the bench's own, the tmpfs goes away with the bench and its
         * children however they end (killed, stopped at a CHECK) */
        s->tmpfs =
                unshare(CLONE_NEWNS) == 0 && mount(NULL, "/", NULL, MS_REC | MS_PRIVATE, NULL) == 0;
        bench_start(&s->e, TIME_SCALE, true);
        s->tmpfs = s->tmpfs && (mkdir(s->e.data, 0755) == 0 || errno == EEXIST) &&
                   mount("tmpfs", s->e.data, "tmpfs", 0, "size=4g") == 0;
        if (!s->tmpfs)
                printf("no tmpfs (not root?): no disk-full fault\n");
        snprintf(text, sizeof(text),
                 "name: soak\ndataset: soak\nsweep:\n"
                 "  turntable: { from: 0, to: %g, step: %g }\n"
                 "  light_arm: { from: 0, to: 300, step: 50 }\n"
                 "cameras: [cam0, cam1]\nlamps: [lamp0, lamp1]\nlaser: false\n"
                 "skip_occluded: false\nskip_glare: false\n",
                 360.0 - 360.0 / steps, 360.0 / steps);
        sess_write(&s->e, "soak.yaml", text, s->file, sizeof(s->file));
        s->planned = sess_planned(&s->e, s->file, NULL);
        bench_watchers_start(&s->w, &s->e, WATCHERS);
        close(sess_start_raw(&s->e, s->file));
}

/* Fails the soak, goniod's status and the session's printed, when the session has not
 * captured anything for STALL_S while running (its directory kept, goniod's log in it). */
static void check_stalled(struct soak *s, int64_t n, const char *state)
{
        static int64_t last = -1;
        static double since;

        if (n != last || strcmp(state, "running")) {
                last = n, since = now_s();
                return;
        }
        if (now_s() - since < STALL_S)
                return;
        print_json("goniod status", ctl_ok(&s->e, "status", NULL));
        print_json("session status", ctl_ok(&s->e, "session", "status", NULL));
        fprintf(stderr, "soak: the session stalled at %lld captures (goniod's log: %s)\n",
                (long long)n, s->e.dir);
        CHECK(!"the session stalled");
}

/* Runs the session to its end, faults at random moments. */
static void soak_run(struct soak *s)
{
        char state[32];
        int64_t n;

        for (;;) {
                double next = now_s() + 1 + rand() % 3;
                while (now_s() < next)
                        usleep(200000);
                n = progress(s, state, sizeof(state));
                if (!strcmp(state, "none"))
                        break;
                check_stalled(s, n, state);
                if (!s->rss_start && n >= (s->killed ? s->planned / 10 + 1000 : 1000))
                        s->rss_start = goniod_rss_mb(s);
                printf("  %lld of %lld captures, %s\n", (long long)n, (long long)s->planned, state);
                fflush(stdout);
                if (!s->killed && n >= s->planned / 10)
                        kill_goniod(s);
                else if (!s->filled && n >= s->planned / 2)
                        fill_disk(s);
                else
                        device_fault(s);
        }
        s->rss_end = goniod_rss_mb(s);
}

int main(int argc, char **argv)
{
        static const struct option opts[] = {{"seed", required_argument, NULL, 's'},
                                             {"captures-scale", required_argument, NULL, 'c'},
                                             {}};
        struct soak s = {0};
        double scale = 1, t0 = bench_now_ms();
        int c;

        srand(1);
        while ((c = getopt_long(argc, argv, "", opts, NULL)) >= 0) {
                CHECK(c == 's' || c == 'c');
                if (c == 's')
                        srand((unsigned)atoi(optarg));
                else
                        scale = atof(optarg);
        }
        CHECK(scale > 0 && scale <= 1);
        setup(&s, scale);
        soak_run(&s);
        bench_watchers_stop(&s.w);
        sess_check_complete(&s.e, "soak", "soak", s.planned); /* exactly once, rows match */
        printf("%lld captures, %d faults injected (%d rig faults), %d kill -9 of goniod, disk "
               "full %s; goniod RSS %.1f MB after 1000 captures, %.1f MB at the end; %.0f s\n",
               (long long)s.planned, s.faults, s.rig_faults, s.kills, s.tmpfs ? "once" : "skipped",
               s.rss_start, s.rss_end, (bench_now_ms() - t0) / 1e3);
        if (s.tmpfs)
                (void)umount2(s.e.data, MNT_DETACH);
        rigenv_stop(&s.e);
        printf("{\"bench\":\"soak\",\"captures\":%lld,\"faults\":%d,\"kills\":%d,\"lost\":0,"
               "\"duplicated\":0,\"rss_start_mb\":%.1f,\"rss_end_mb\":%.1f}\n",
               (long long)s.planned, s.faults, s.kills, s.rss_start, s.rss_end);
        return 0;
}
