/* main.c - gonio-sim: runs the simulated rig of a rig file. Emulates the Modbus
 * controllers on pseudo-terminals / loopback TCP, renders camera frames on the frame
 * socket, writes where everything listens (the ports file, JSON) and prints it, then
 * "ready", and runs until SIGTERM or SIGINT. See docs/sim.md. */
#include <errno.h>
#include <fcntl.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <jansson.h>

#include "common/fileio.h"
#include "common/log.h"
#include "common/rigconf.h"
#include "common/sigroute.h"
#include "drivers/registry.h"
#include "gonio_version.h"
#include "sim/frame_server.h"
#include "sim/modbus_emu.h"
#include "sim/render/render.h"

struct args {
        const char *rig, *dir, *ports_file, *render_log, *control;
        double time_scale;
};

DEFINE_TRIVIAL_CLEANUP_FUNC(struct rig_config *, rigconf_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_scene *, sim_scene_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_emu *, sim_emu_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_frame_server *, sim_frame_server_free);

static void usage(FILE *f)
{
        fputs("Usage: gonio-sim --rig FILE [--dir DIR] [--time-scale X] [--ports-file FILE]\n"
              "                 [--render-log FILE] [--control PATH]\n"
              "  --rig FILE         rig file (YAML) to simulate\n"
              "  --dir DIR          directory of the ports (sets GONIO_SIM_DIR; created)\n"
              "  --time-scale X     emulated seconds per real second (default 1)\n"
              "  --ports-file FILE  write the ports (JSON) to FILE as well\n"
              "  --render-log FILE  append one JSON line per rendered frame to FILE\n"
              "  --control PATH     control socket (state, geometry, inject); default\n"
              "                     DIR/control.sock with --dir, else none\n"
              "  --version          print the version and exit\n",
              f);
}

/* Returns 1 to run, 0 after --help or --version, or -EINVAL after a usage error (printed). */
static int parse_args(int argc, char **argv, struct args *a)
{
        static const struct option opts[] = {
                {"rig", required_argument, NULL, 'r'},
                {"dir", required_argument, NULL, 'd'},
                {"time-scale", required_argument, NULL, 't'},
                {"ports-file", required_argument, NULL, 'p'},
                {"render-log", required_argument, NULL, 'l'},
                {"control", required_argument, NULL, 'c'},
                {"help", no_argument, NULL, 'h'},
                {"version", no_argument, NULL, 'V'},
                {},
        };
        char *end;
        int c;

        *a = (struct args){.time_scale = 1.0};
        while ((c = getopt_long(argc, argv, "r:d:t:p:l:c:hV", opts, NULL)) >= 0) {
                switch (c) {
                case 'r':
                        a->rig = optarg;
                        break;
                case 'd':
                        a->dir = optarg;
                        break;
                case 't':
                        a->time_scale = strtod(optarg, &end);
                        if (*end || !(a->time_scale > 0.0 && a->time_scale <= 1000.0))
                                return log_error_errno(SYNTHETIC_ERRNO(EINVAL),
                                                       "--time-scale: '%s' is not in (0, 1000]",
                                                       optarg);
                        break;
                case 'p':
                        a->ports_file = optarg;
                        break;
                case 'l':
                        a->render_log = optarg;
                        break;
                case 'c':
                        a->control = optarg;
                        break;
                case 'h':
                        usage(stdout);
                        return 0;
                case 'V':
                        printf("gonio-sim %s\n", GONIO_VERSION);
                        return 0;
                default:
                        usage(stderr);
                        return -EINVAL;
                }
        }
        if (!a->rig || optind < argc) {
                usage(stderr);
                return -EINVAL;
        }
        return 1;
}

/* mkdir -p */
static int make_dir(const char *dir)
{
        char path[RIG_PATH_MAX];

        if (snprintf(path, sizeof path, "%s", dir) >= (int)sizeof path)
                return -ENAMETOOLONG;
        for (char *p = path + 1;; p++) {
                bool last = *p == '\0';
                if (*p != '/' && !last)
                        continue;
                *p = '\0';
                if (mkdir(path, 0755) < 0 && errno != EEXIST)
                        return -errno;
                if (last)
                        return 0;
                *p = '/';
        }
}

/* {"rig": NAME, "buses": {NAME: {"type": T, "path": P, "pty": TTY | "host": H, "port": N}}} */
static json_t *ports_json(const struct rig_config *rc, struct sim_emu *emu)
{
        json_t *buses = json_object();

        for (size_t i = 0; buses && i < rc->n_buses; i++) {
                const struct rig_bus_conf *b = &rc->buses[i];
                json_t *o = b->type == RIG_BUS_MODBUS_TCP
                                    ? json_pack("{s:s, s:s, s:i}", "type",
                                                rigconf_bus_type_name(b->type), "host", "127.0.0.1",
                                                "port", sim_emu_tcp_port(emu, b->name))
                                    : json_pack("{s:s, s:s}", "type",
                                                rigconf_bus_type_name(b->type), "path", b->port);
                const char *pty = sim_emu_pty(emu, b->name);
                if (!o || (pty && json_object_set_new(o, "pty", json_string(pty)) < 0) ||
                    json_object_set_new(buses, b->name, o) < 0)
                        json_decref(TAKE_PTR(buses));
        }
        return json_pack("{s:s, s:o}", "rig", rc->name, "buses", buses);
}

/* Writes the ports to path (atomically) and to stdout. */
static int publish_ports(const struct rig_config *rc, struct sim_emu *emu, const char *path)
{
        json_auto_t *o = ports_json(rc, emu);
        _cleanup_free_ char *text = o ? json_dumps(o, JSON_INDENT(2)) : NULL;
        int r;

        if (!text)
                return log_error_errno(SYNTHETIC_ERRNO(ENOMEM), "Out of memory");
        if (path && (r = gn_write_atomic(AT_FDCWD, path, text, strlen(text), NULL)) < 0)
                return log_error_errno(r, "Cannot write %s: %m", path);
        if (json_dumpf(o, stdout, JSON_COMPACT) < 0)
                return -EIO;
        printf("\nready\n");
        return fflush(stdout) == 0 ? 0 : -EIO;
}

static int load(const struct args *a, struct rig_config **rc, struct sim_scene **scene)
{
        char err[512] = "";

        if (a->dir) {
                int r = make_dir(a->dir);
                if (r < 0)
                        return log_error_errno(r, "Cannot create %s: %m", a->dir);
                if (setenv("GONIO_SIM_DIR", a->dir, 1) < 0)
                        return log_error_errno(errno, "setenv: %m");
        }
        int r = rigconf_load(a->rig, registry_backends, rc, err, sizeof err);
        if (r < 0)
                return log_error_errno(r, "%s", err[0] ? err : a->rig);
        r = sim_scene_new(*rc, scene, err, sizeof err);
        if (r < 0)
                return log_error_errno(r, "Scene: %s", err[0] ? err : "cannot build");
        return 0;
}

static int run(const struct args *a)
{
        _cleanup_free_ char *control = NULL; /* first: freed after the frame server below */
        _cleanup_(rigconf_freep) struct rig_config *rc = NULL;
        _cleanup_(sim_scene_freep) struct sim_scene *scene = NULL;
        _cleanup_(sim_emu_freep) struct sim_emu *emu = NULL;
        _cleanup_(sim_frame_server_freep) struct sim_frame_server *fs = NULL;
        sigset_t sigs;
        int sig, r;

        if (a->control)
                control = strdup(a->control);
        else if (a->dir && asprintf(&control, "%s/control.sock", a->dir) < 0)
                control = NULL;
        if ((a->control || a->dir) && !control)
                return -ENOMEM;
        /* Blocked before any thread of ours starts, so that only sigwait() below takes them. */
        sigemptyset(&sigs);
        sigaddset(&sigs, SIGTERM);
        sigaddset(&sigs, SIGINT);
        r = gn_sigroute_here((const int[]){SIGTERM, SIGINT}, 2);
        if (r < 0)
                return r;

        r = load(a, &rc, &scene);
        if (r >= 0)
                r = sim_emu_new(rc, a->time_scale, &emu);
        if (r >= 0)
                r = sim_frame_server_new(rc, scene, emu,
                                         &(struct sim_fs_options){.time_scale = a->time_scale,
                                                                  .render_log = a->render_log,
                                                                  .control = control},
                                         &fs);
        if (r >= 0)
                r = publish_ports(rc, emu, a->ports_file);
        if (r < 0)
                return r;
        if (sigwait(&sigs, &sig) != 0)
                return -EINTR;
        log_info("%s: shutting down", strsignal(sig));
        if (a->ports_file)
                (void)unlink(a->ports_file);
        return 0;
}

int main(int argc, char **argv)
{
        struct args a;

        gn_log_set_ident("gonio-sim");
        int r = parse_args(argc, argv, &a);
        if (r <= 0)
                return r < 0 ? 2 : 0;
        return run(&a) < 0 ? 1 : 0;
}
