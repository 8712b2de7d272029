/* model_web.c - gonioctl model export --web DIR MODEL and gonioctl model view MODEL: the
 * relighting viewer (appearance/webexport.h) written as a static folder, or written into a
 * temporary folder and served over HTTP (common/httpd.h), loopback unless told otherwise,
 * until SIGINT or SIGTERM; with a BRDF model beside the SH model, its environment mode too
 * (--spheres N: its shadows' sphere set). Offline: never talks to goniod. docs/viewer.md. */
#include <errno.h>
#include <getopt.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <fcntl.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "appearance/export.h"
#include "appearance/model.h"
#include "appearance/webexport.h"
#include "client/cmd.h"
#include "client/model.h"
#include "common/cleanup.h"
#include "common/httpd.h"
#include "common/sigroute.h"
#include "drivers/registry.h"

#define MAX_ENVMAPS 16

struct web_cli {
        const char *model, *dir, *bind;
        const char *envmaps[MAX_ENVMAPS + 1];
        int n_envmaps, port, spheres;
        bool view;
};

static int web_usage(const struct web_cli *w, const char *fmt, const char *arg)
{
        fprintf(stderr, "gonioctl: model %s: ", w->view ? "view" : "export");
        fprintf(stderr, fmt, arg);
        fprintf(stderr, "\nusage: gonioctl model %s\n",
                w->view ? "view MODEL [--bind ADDR] [--port N] [--envmap FILE]... [--spheres N]"
                        : "export --web DIR MODEL [--envmap FILE]... [--spheres N]");
        return EXIT_USAGE;
}

static int web_option(struct web_cli *w, int c, const char *arg)
{
        char *end;

        switch (c) {
        case 'w':
                w->dir = arg;
                return 0;
        case 'e':
                if (w->n_envmaps == MAX_ENVMAPS)
                        return web_usage(w, "at most 16 --envmap, not %s", "more");
                w->envmaps[w->n_envmaps++] = arg;
                return 0;
        case 'b':
                w->bind = arg;
                return 0;
        case 'p':
                w->port = (int)strtol(arg, &end, 10);
                return *end || end == arg || w->port < 0 || w->port > 65535
                               ? web_usage(w, "bad port '%s': expected 0 to 65535", arg)
                               : 0;
        case 's':
                w->spheres = (int)strtol(arg, &end, 10);
                return *end || end == arg || w->spheres < 1 || w->spheres > AP_SPHERES_MAX
                               ? web_usage(w, "bad --spheres '%s': expected 1 to 1024", arg)
                               : 0;
        }
        return web_usage(w, "bad option '%s'", arg);
}

static int parse_web(int argc, char **argv, struct web_cli *w)
{
        static const struct option opts[] = {
                {"web", required_argument, NULL, 'w'},     {"envmap", required_argument, NULL, 'e'},
                {"bind", required_argument, NULL, 'b'},    {"port", required_argument, NULL, 'p'},
                {"spheres", required_argument, NULL, 's'}, {NULL, 0, NULL, 0}};
        int c, r;

        *w = (struct web_cli){.view = strcmp(argv[0], "view") == 0, .bind = "127.0.0.1"};
        optind = 0;
        opterr = 0;
        while ((c = getopt_long(argc, argv, "+", opts, NULL)) != -1 || optind < argc) {
                if (c == -1) { /* a positional word: the model, then options may follow */
                        if (w->model)
                                return web_usage(w, "unexpected argument '%s'", argv[optind]);
                        w->model = argv[optind++];
                        continue;
                }
                if ((c == 'w' && w->view) || (!w->view && (c == 'b' || c == 'p')) || c == '?')
                        return web_usage(w, "bad option '%s'", argv[optind - 1]);
                if ((r = web_option(w, c, optarg)) != 0)
                        return r;
        }
        if (!w->model || (!w->view && !w->dir))
                return web_usage(w, "%s",
                                 w->view ? "MODEL is required"
                                         : "--web DIR and MODEL are required");
        return 0;
}

static int export_web(const struct web_cli *w, const char *dir)
{
        struct ap_web_opts o = {w->n_envmaps ? w->envmaps : NULL, registry_backends, w->spheres};
        char err[1024] = "";
        int r = ap_web_export(w->model, dir, &o, err, sizeof(err));

        if (r < 0) {
                fprintf(stderr, "gonioctl: model %s: %s\n", w->view ? "view" : "export",
                        err[0] ? err : strerror(-r));
                return cmd_exit_for_errno(r == -ENOENT || r == -EBADMSG ? -EINVAL : r);
        }
        return 0;
}

/* Serves the folder root on w's address until SIGINT or SIGTERM. */
static int serve(const struct web_cli *w, const char *root)
{
        static const int sigs[] = {SIGINT, SIGTERM};
        _cleanup_(sd_event_unrefp) sd_event *ev = NULL;
        _cleanup_close_ int fd = open(root, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        struct httpd *h = NULL;
        int r;

        if (fd < 0 || (r = gn_sigroute_here(sigs, 2)) < 0 || (r = sd_event_new(&ev)) < 0 ||
            (r = sd_event_add_signal(ev, NULL, SIGINT, NULL, NULL)) < 0 ||
            (r = sd_event_add_signal(ev, NULL, SIGTERM, NULL, NULL)) < 0)
                r = fd < 0 ? -errno : r;
        else if ((r = httpd_new(ev, fd, w->bind, (uint16_t)w->port, &h)) < 0)
                fprintf(stderr, "gonioctl: model view: cannot listen on %s port %d: %s\n", w->bind,
                        w->port, strerror(-r));
        if (r < 0)
                return r == -EADDRINUSE ? EXIT_BUSY : cmd_exit_for_errno(r);
        if (strncmp(w->bind, "127.", 4) != 0 && strcmp(w->bind, "::1") != 0)
                fprintf(stderr,
                        "gonioctl: model view: listening beyond loopback on %s: anyone "
                        "who reaches this machine can see the model\n",
                        w->bind);
        printf("serving the viewer of %s at http://%s%s%s:%u/ (Ctrl-C stops)\n", w->model,
               strchr(w->bind, ':') ? "[" : "", w->bind, strchr(w->bind, ':') ? "]" : "",
               httpd_port(h));
        fflush(stdout);
        r = sd_event_loop(ev);
        httpd_free(h);
        return r < 0 ? cmd_exit_for_errno(r) : EXIT_OK;
}

/* model view: the viewer written into a temporary folder, served, removed. */
static int model_view(const struct web_cli *w)
{
        char tmp[] = "/tmp/gonio-view-XXXXXX", dir[64];
        int e;

        if (!mkdtemp(tmp)) {
                fprintf(stderr, "gonioctl: model view: cannot create %s: %m\n", tmp);
                return EXIT_STORAGE;
        }
        snprintf(dir, sizeof(dir), "%s/web", tmp);
        if ((e = export_web(w, dir)) == 0)
                e = serve(w, dir);
        ap_remove_tree(tmp);
        return e;
}

int model_web_command(int argc, char **argv)
{
        struct web_cli w;
        int e;

        if ((e = parse_web(argc, argv, &w)) != 0)
                return e;
        if (w.view)
                return model_view(&w);
        if ((e = export_web(&w, w.dir)) != 0)
                return e;
        printf("viewer of %s written into %s: open %s/index.html\n", w.model, w.dir, w.dir);
        return EXIT_OK;
}
