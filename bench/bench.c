/* bench.c - helpers shared by the benchmarks on goniod and gonio-sim (see bench.h). */
#include <errno.h>
#include <libgen.h>
#include <limits.h>
#include <math.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "bench.h"
#include "common/clock.h"
#include "common/pose.h"
#include "tests/test.h"
#include "common/sortx.h"

/* The programs of the build tree this program lives in, as the harness takes them. */
static char **tools(void)
{
        static const char *const rel[] = {"daemon/goniod", "client/gonioctl", "sim/gonio-sim"};
        static char paths[3][PATH_MAX];
        static char *argv[] = {"bench", paths[0], paths[1], paths[2], NULL};
        char self[PATH_MAX];
        ssize_t n = readlink("/proc/self/exe", self, sizeof(self) - 1);
        const char *build;

        CHECK(n > 0);
        self[n] = 0;
        build = dirname(dirname(self)); /* BUILD/bench/NAME -> BUILD */
        for (int i = 0; i < 3; i++)
                snprintf(paths[i], PATH_MAX, "%s/%s", build, rel[i]);
        return argv;
}

void bench_start(struct rigenv *e, double time_scale, bool log)
{
        if (log)
                rigenv_start_logged(e, tools(), time_scale);
        else
                rigenv_start(e, tools(), time_scale);
}

void bench_start_rig(struct rigenv *e, double time_scale, const char *rig_text)
{
        rigenv_start_rig(e, tools(), time_scale, rig_text);
}

double bench_now_ms(void)
{
        return (double)gn_monotonic_ns() * 1e-6;
}

double bench_cpu_s(pid_t pid)
{
        char path[64], buf[1024], *p;
        unsigned long utime, stime;
        FILE *f;

        snprintf(path, sizeof(path), "/proc/%d/stat", (int)pid);
        f = fopen(path, "re");
        CHECK(f);
        CHECK(fgets(buf, sizeof(buf), f));
        fclose(f);
        p = strrchr(buf, ')'); /* the command name may hold spaces */
        CHECK(p && sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &utime,
                          &stime) == 2);
        return (double)(utime + stime) / (double)sysconf(_SC_CLK_TCK);
}

void bench_add(struct bench_samples *s, double v)
{
        if (s->n == s->cap) {
                s->cap = s->cap ? 2 * s->cap : 1024;
                s->v = realloc(s->v, s->cap * sizeof(*s->v));
                CHECK(s->v);
        }
        s->v[s->n++] = v;
}

double bench_quantile(struct bench_samples *s, double q)
{
        size_t i;

        if (s->n == 0)
                return NAN;
        qsort(s->v, s->n, sizeof(*s->v), gn_cmp_double);
        i = (size_t)ceil(q * (double)s->n);
        return s->v[i > 0 ? i - 1 : 0];
}

void bench_samples_clear(struct bench_samples *s)
{
        free(s->v);
        *s = (struct bench_samples){0};
}

int bench_client(struct rigenv *e, const char *name)
{
        char req[256];
        int fd = raw_connect(e);
        json_t *r;

        CHECK(fd >= 0);
        snprintf(req, sizeof(req),
                 "{\"jsonrpc\":\"2.0\",\"id\":0,\"method\":\"hello\",\"params\":"
                 "{\"client\":\"%s\",\"protocol\":1}}\n",
                 name);
        r = raw_call(fd, req);
        CHECK(json_object_get(r, "result"));
        json_decref(r);
        return fd;
}

ssize_t bench_lines_read(struct bench_lines *l, bool wait, void (*fn)(json_t *msg, void *ud),
                         void *ud)
{
        struct pollfd pfd = {.fd = l->fd, .events = POLLIN};
        ssize_t n;
        char *start = l->buf, *nl;

        if (poll(&pfd, 1, wait ? 30000 : 0) == 0)
                return -EAGAIN;
        n = read(l->fd, l->buf + l->len, sizeof(l->buf) - 1 - l->len);
        if (n <= 0)
                return n < 0 ? -errno : 0;
        l->len += n;
        l->buf[l->len] = 0;
        while ((nl = strchr(start, '\n'))) {
                json_t *msg;

                *nl = 0;
                msg = json_loads(start, 0, NULL);
                fn(msg, ud);
                json_decref(msg);
                start = nl + 1;
        }
        l->len -= start - l->buf;
        memmove(l->buf, start, l->len);
        CHECK(l->len < sizeof(l->buf) - 1); /* a line longer than the buffer */
        return n;
}

double bench_sim_angle(struct rigenv *e, int *fd, int role)
{
        static const char req[] = "{\"cmd\":\"state\"}\n";
        char reply[4096], path[400];
        size_t len = 0;
        json_t *r, *deg;
        double a;

        if (*fd < 0) {
                snprintf(path, sizeof(path), "%s/control.sock", e->simdir);
                *fd = test_unix_connect(path);
                CHECK(*fd >= 0);
        }
        CHECK(write(*fd, req, sizeof(req) - 1) == (ssize_t)sizeof(req) - 1);
        while (len == 0 || reply[len - 1] != '\n') {
                ssize_t n = read(*fd, reply + len, sizeof(reply) - 1 - len);
                CHECK(n > 0);
                len += n;
        }
        reply[len] = 0;
        r = json_loads(reply, 0, NULL);
        deg = json_object_get(json_object_get(r, "state"), gn_role_name(role));
        CHECK(json_is_number(deg));
        a = json_number_value(deg);
        json_decref(r);
        return a;
}

const char *bench_session(struct rigenv *e, const char *name, bool big_moves, char *path,
                          size_t len)
{
        char text[1024], file[128];

        snprintf(text, sizeof(text),
                 "name: %s\n"
                 "dataset: %s\n"
                 "sweep:\n"
                 "  turntable: %s\n"
                 "  light_arm: %s\n"
                 "cameras: [cam0, cam1]\n"
                 "lamps: [lamp0, lamp1]\n"
                 "laser: %s\n"
                 "skip_occluded: false\n"
                 "skip_glare: false\n",
                 name, name, big_moves ? "[0, 180]" : "{ from: 0, to: 345, step: 15 }",
                 big_moves ? "[0, 180]" : "[0, 120]", big_moves ? "false" : "true");
        snprintf(file, sizeof(file), "%s.yaml", name);
        return sess_write(e, file, text, path, len);
}

static void count_stored(json_t *msg, void *ud)
{
        const char *m = json_string_value(json_object_get(msg, "method"));

        if (m && strcmp(m, "capture.stored") == 0)
                (*(long *)ud)++;
}

static void *watch_loop(void *ud)
{
        struct bench_watchers *w = ud;
        struct pollfd *p = calloc(w->n, sizeof(*p));

        CHECK(p);
        for (int i = 0; i < w->n; i++)
                p[i] = (struct pollfd){.fd = w->lines[i].fd, .events = POLLIN};
        while (!atomic_load(&w->quit)) {
                if (poll(p, w->n, 50) <= 0)
                        continue;
                for (int i = 0; i < w->n; i++)
                        if (p[i].revents &&
                            bench_lines_read(&w->lines[i], false, count_stored, &w->stored[i]) == 0)
                                p[i].fd = -1; /* goniod closed it: its count falls short */
        }
        free(p);
        return NULL;
}

void bench_watchers_start(struct bench_watchers *w, struct rigenv *e, int n)
{
        *w = (struct bench_watchers){.n = n};
        w->lines = calloc(n, sizeof(*w->lines));
        w->stored = calloc(n, sizeof(*w->stored));
        CHECK(w->lines && w->stored);
        for (int i = 0; i < n; i++)
                w->lines[i].fd = bench_client(e, "bench-watcher");
        CHECK(pthread_create(&w->thread, NULL, watch_loop, w) == 0);
}

long bench_watchers_stop(struct bench_watchers *w)
{
        long least = -1;

        atomic_store(&w->quit, true);
        CHECK(pthread_join(w->thread, NULL) == 0);
        for (int i = 0; i < w->n; i++) {
                close(w->lines[i].fd);
                if (least < 0 || w->stored[i] < least)
                        least = w->stored[i];
        }
        free(w->lines);
        free(w->stored);
        return least;
}

/* What one session run measured. */
struct run {
        long stored;
        double t_first_ms, t_last_ms;
        bool ended;
        char how[16]; /* "ended" of the last session.state */
};

static void on_control(json_t *msg, void *ud)
{
        struct run *r = ud;
        const char *m = json_string_value(json_object_get(msg, "method"));
        json_t *params = json_object_get(msg, "params");
        const char *state = json_string_value(json_object_get(params, "state"));

        if (m && strcmp(m, "capture.stored") == 0) {
                r->t_last_ms = bench_now_ms();
                if (r->stored++ == 0)
                        r->t_first_ms = r->t_last_ms;
        } else if (m && strcmp(m, "session.state") == 0 && state && strcmp(state, "none") == 0) {
                r->ended = true;
                snprintf(r->how, sizeof(r->how), "%s",
                         json_string_value(json_object_get(params, "ended")));
        }
}

double bench_run_session(struct rigenv *e, const char *name, int64_t *n, double *cpu_ms,
                         double span_ms[2])
{
        struct bench_lines *l = calloc(1, sizeof(*l));
        struct run r = {0};
        char file[400];
        double cpu;

        CHECK(l);
        bench_session(e, name, false, file, sizeof(file));
        *n = sess_planned(e, file, NULL);
        cpu = bench_cpu_s(e->daemon);
        l->fd = sess_start_raw(e, file);
        while (!r.ended)
                CHECK(bench_lines_read(l, true, on_control, &r) > 0);
        *cpu_ms += (bench_cpu_s(e->daemon) - cpu) * 1e3 / (double)*n;
        close(l->fd);
        free(l);
        CHECK_STR(r.how, "done");
        sess_check_complete(e, name, name, *n);
        CHECK(r.stored > 1 && r.t_last_ms > r.t_first_ms);
        if (span_ms) {
                span_ms[0] = r.t_first_ms;
                span_ms[1] = r.t_last_ms;
        }
        return (r.stored - 1) * 1000.0 / (r.t_last_ms - r.t_first_ms);
}
