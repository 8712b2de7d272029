/* manager.c - goniod's top-level object: one sd-event loop that owns the rig,
 * the control server and the dataset store, and shuts them down in order. */
#include <errno.h>
#include <signal.h>
#include <string.h>
#include <sys/stat.h>
#include <systemd/sd-daemon.h>
#include <systemd/sd-event.h>

#include "common/log.h"
#include "manager.h"

void manager_notify(void *userdata, const char *method, json_t *params)
{
        struct manager *m = userdata;

        if (m->server)
                server_broadcast(m->server, method, params);
        else
                json_decref(params);
}

static int make_dir(const char *path)
{
        if (mkdir(path, 0775) < 0 && errno != EEXIST)
                return -errno;
        return 0;
}

int manager_new(const char *rig_path, const char *socket_path, const char *data_dir,
                struct manager **ret)
{
        struct manager *m = calloc(1, sizeof(*m));
        char err[512];
        int r;

        if (!m)
                return -ENOMEM;
        snprintf(m->data_dir, sizeof(m->data_dir), "%s", data_dir);
        r = rigconf_load(rig_path, &m->rc, err, sizeof(err));
        if (r < 0) {
                log_error("%s", err);
                goto fail;
        }
        if ((r = make_dir(data_dir)) < 0) {
                log_error_errno(r, "Cannot create data directory %s: %m", data_dir);
                goto fail;
        }
        if ((r = sd_event_default(&m->event)) < 0 ||
            (r = sd_event_add_signal(m->event, NULL, SIGTERM | SD_EVENT_SIGNAL_PROCMASK, NULL,
                                     NULL)) < 0 ||
            (r = sd_event_add_signal(m->event, NULL, SIGINT | SD_EVENT_SIGNAL_PROCMASK, NULL,
                                     NULL)) < 0 ||
            (r = sd_event_set_watchdog(m->event, true)) < 0)
                goto fail;
        r = rig_new(m->event, m->rc, manager_notify, m, &m->rig);
        if (r < 0)
                goto fail;
        if (strcmp(rig_state(m->rig), "fault") == 0)
                log_warning("rig starts in fault state; fix it and call fault.clear");
        r = server_new(m->event, socket_path, manager_methods, m, &m->server);
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

        (void)sd_notify(false, "READY=1\nSTATUS=serving");
        log_info("rig '%s' ready (%s)", m->rc->name, rig_state(m->rig));
        r = sd_event_loop(m->event);
        (void)sd_notify(false, "STOPPING=1");
        return r;
}

struct manager *manager_free(struct manager *m)
{
        if (!m)
                return NULL;
        m->server = server_free(m->server);
        m->pool = ds_pool_free(m->pool); /* completes pending stores */
        m->ds = ds_close(m->ds);
        m->rig = rig_free(m->rig);       /* safe state */
        rigconf_free(m->rc);
        sd_event_unref(m->event);
        free(m);
        return NULL;
}
