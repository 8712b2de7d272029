/* manager.c - goniod's top-level object: one sd-event loop that owns the rig,
 * the control server and the dataset store, and shuts them down in order. */
#include <errno.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>
#include <systemd/sd-event.h>

#include "common/log.h"
#include "common/sigroute.h"
#include "drivers/registry.h"
#include "calcopy.h"
#include "datasets.h"
#include "manager.h"
#include "protocol/proto.h"
#include "web.h"

/* What goniod does, for systemd's STATUS= (systemctl status): the shutdown, a fault, a
 * session's progress, a scan, else the rig's state ("idle", "moving"...). */
static void status_line(struct manager *m, char *buf, size_t len)
{
        const char *state = rig_state(m->rig);
        json_t *ss;

        if (m->shutdown_deadline)
                snprintf(buf, len, "stopping: bringing the rig to its safe state");
        else if (strcmp(state, "fault") == 0)
                snprintf(buf, len, "fault: %s", rig_last_error(m->rig));
        else if (session_active(m->session) && (ss = session_status(m->session))) {
                snprintf(buf, len, "session '%s' %s: %lld/%lld captures (rig %s)",
                         json_string_value(json_object_get(ss, "name")),
                         json_string_value(json_object_get(ss, "state")),
                         (long long)json_integer_value(json_object_get(ss, "captured")),
                         (long long)json_integer_value(json_object_get(ss, "planned")), state);
                json_decref(ss);
        } else if (scan_active(m->scan))
                snprintf(buf, len, "continuous scan (rig %s)", state);
        else
                snprintf(buf, len, "%s", state);
}

/* Sends STATUS= to systemd when what goniod does has changed (and READY=1 or STOPPING=1 with
 * it when extra says so). */
static void update_status(struct manager *m, const char *extra)
{
        char line[sizeof(m->status)];

        if (!m->notify)
                return;
        status_line(m, line, sizeof(line));
        if (!extra && strcmp(line, m->status) == 0)
                return;
        snprintf(m->status, sizeof(m->status), "%s", line);
        (void)sd_notifyf(false, "%sSTATUS=%s", extra ? extra : "", line);
}

void manager_notify_json(struct manager *m, const char *method, json_t *params)
{
        if (m->server)
                server_broadcast(m->server, method, params);
        else
                json_decref(params);
        web_notify(m->web);
        update_status(m, NULL);
}

/* The protocol edge of rig events: the notifications of docs/protocol.md. */
void manager_on_rig_event(void *userdata, const struct rig_event *ev)
{
        struct manager *m = userdata;

        switch (ev->type) {
        case RIG_EVENT_STATE:
                return manager_notify_json(m, "state.changed",
                                           json_pack("{ss}", "state", ev->state));
        case RIG_EVENT_AXIS_MOVED:
                return manager_notify_json(m, "axis.moved",
                                           json_pack("{sssfsb}", "axis", ev->device, "position",
                                                     ev->position, "moving", ev->moving));
        case RIG_EVENT_MOVE_DONE:
                return manager_notify_json(m, "move.done",
                                           json_pack("{sssfsb}", "axis", ev->device, "position",
                                                     ev->position, "moving", false));
        case RIG_EVENT_SWITCH:
                return manager_notify_json(m, "switch.changed",
                                           json_pack("{sssb}", "name", ev->device, "on", ev->on));
        case RIG_EVENT_FAULT:
                return manager_notify_json(m, "fault",
                                           json_pack("{sssiss}", "device", ev->device, "code",
                                                     proto_errno_to_code(ev->error), "message",
                                                     ev->message));
        }
}

/* The protocol edge of stored rows: capture.stored. */
static void on_stored_row(void *userdata, const struct ds_capture *c)
{
        manager_notify_json(userdata, "capture.stored",
                            json_pack("{sIssssss}", "id", (json_int_t)c->id, "camera", c->camera,
                                      "file", c->file, "sha256", c->sha256));
}

static int make_dir(const char *path)
{
        if (mkdir(path, 0775) < 0 && errno != EEXIST)
                return -errno;
        return 0;
}

/* Leaves the loop once the rig has reached its safe state (or after 5 s). */
static int on_shutdown_tick(sd_event_source *s, uint64_t usec, void *userdata)
{
        struct manager *m = userdata;
        uint64_t now = 0;

        sd_event_now(m->event, CLOCK_MONOTONIC, &now);
        if (rig_pending(m->rig) == 0 || now >= m->shutdown_deadline)
                return sd_event_exit(m->event, 0);
        sd_event_source_set_time_relative(s, 20 * 1000);
        return sd_event_source_set_enabled(s, SD_EVENT_ONESHOT);
}

static int on_signal(sd_event_source *s, const struct signalfd_siginfo *si, void *userdata)
{
        struct manager *m = userdata;
        sd_event_source *tick = NULL;

        if (m->shutdown_deadline)
                return 0;
        log_info("shutting down: bringing the rig to its safe state");
        sd_event_now(m->event, CLOCK_MONOTONIC, &m->shutdown_deadline);
        m->shutdown_deadline += 5 * 1000 * 1000ULL;
        update_status(m, "STOPPING=1\n");
        rig_shutdown(m->rig); /* no new motion or light from a session, a scan or a client */
        if (sd_event_add_time_relative(m->event, &tick, CLOCK_MONOTONIC, 0, 0, on_shutdown_tick,
                                       m) < 0)
                return sd_event_exit(m->event, 0);
        sd_event_source_set_floating(tick, true);
        sd_event_source_unref(tick);
        return 0;
}

/* Listens on the sockets systemd passed, else binds the operator and admin sockets. */
static int listen_sockets(struct manager *m, const char *socket_path, const char *admin_path)
{
        int r = server_listen_systemd(m->server);

        if (r != 0)
                return r;
        r = server_listen(m->server, socket_path, SRV_OPERATOR);
        return r < 0 ? r : server_listen(m->server, admin_path, SRV_ADMIN);
}

int manager_new(const char *rig_path, const char *socket_path, const char *admin_path,
                const char *data_dir, struct manager **ret)
{
        struct manager *m = calloc(1, sizeof(*m));
        char err[512];
        int r;

        if (!m)
                return -ENOMEM;
        snprintf(m->data_dir, sizeof(m->data_dir), "%s", data_dir);
        r = rigconf_load(rig_path, registry_backends, &m->rc, err, sizeof(err));
        if (r < 0) {
                log_error("%s", err);
                goto fail;
        }
        calcopy_warn(m->rc);
        if ((r = make_dir(data_dir)) < 0) {
                log_error_errno(r, "Cannot create data directory %s: %m", data_dir);
                goto fail;
        }
        /* Blocked from here; taken only once manager_run starts (a signal during the start,
         * while opening the devices runs the loop, would end it half built). */
        if ((r = gn_sigroute_here((const int[]){SIGTERM, SIGINT}, 2)) < 0 ||
            (r = sd_event_default(&m->event)) < 0 ||
            (r = sd_event_set_watchdog(m->event, true)) < 0)
                goto fail;
        /* Claim the socket first: a second goniod must not touch the rig. */
        r = server_new(m->event, manager_methods, m, &m->server);
        if (r >= 0)
                r = listen_sockets(m, socket_path, admin_path);
        if (r < 0)
                goto fail;
        server_on_close(m->server, manager_client_gone, m);
        r = rig_new(m->event, m->rc, manager_on_rig_event, m, &m->rig);
        if (r < 0)
                goto fail;
        r = capture_new(m->event, m->rig, on_stored_row, m, &m->capture);
        if (r < 0)
                goto fail;
        r = session_runner_new(m, &m->session);
        if (r < 0)
                goto fail;
        r = scan_new(m, &m->scan);
        if (r < 0)
                goto fail;
        if (strcmp(rig_state(m->rig), "fault") == 0)
                log_warning("rig starts in fault state; fix it and call fault.clear");
        r = server_start(m->server);
        if (r < 0)
                goto fail;
        *ret = m;
        return 0;
fail:
        manager_free(m);
        return r;
}

int manager_run(struct manager *m)
{
        int r;

        /* a signal pending since the start is taken now: an orderly shutdown */
        if ((r = sd_event_add_signal(m->event, NULL, SIGTERM | SD_EVENT_SIGNAL_PROCMASK, on_signal,
                                     m)) < 0 ||
            (r = sd_event_add_signal(m->event, NULL, SIGINT | SD_EVENT_SIGNAL_PROCMASK, on_signal,
                                     m)) < 0)
                return r;
        m->notify = getenv("NOTIFY_SOCKET") != NULL; /* from here on everything is built */
        update_status(m, "READY=1\n");
        log_info("rig '%s' ready (%s)", m->rc->name, rig_state(m->rig));
        ds_forbid_thread(true); /* no dataset I/O on the loop while it serves */
        r = sd_event_loop(m->event);
        m->notify = false; /* the teardown's events are not news for systemd */
        ds_forbid_thread(false);
        return r;
}

struct manager *manager_free(struct manager *m)
{
        if (!m)
                return NULL;
        /* First the users of the others: from here on the session and the scan only count
         * their completions down, whatever frees them (a store, a switch, a load). */
        if (m->session)
                session_runner_stop(m->session);
        if (m->scan)
                scan_abandon(m->scan);
        m->web = web_free(m->web); /* before what its handlers and pictures read */
        datasets_free(m); /* answers the dataset jobs while the capture can take a dataset */
        m->server = server_free(m->server);           /* pending requests outlive their clients */
        m->capture = capture_free(m->capture);        /* completes pending stores */
        m->rig = rig_free(m->rig);                    /* safe state; drops its completions */
        m->session = session_runner_free(m->session); /* last: the above may call it back */
        m->scan = scan_free(m->scan);
        rigconf_free(m->rc);
        sd_event_unref(m->event);
        free(m);
        return NULL;
}
