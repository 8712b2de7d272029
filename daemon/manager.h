/* manager.h - goniod's top-level object: the event loop, the rig, the control
 * server, and the open dataset with its storage pool. */
#pragma once

#include <limits.h>

#include "common/rigconf.h"
#include "capture.h"
#include "rig.h"
#include "server.h"
#include "scan.h"
#include "session.h"

typedef struct sd_event sd_event;
struct workq;
struct web;

struct manager {
        sd_event *event;
        struct rig_config *rc;
        struct rig *rig;
        struct server *server;
        char data_dir[PATH_MAX];
        struct capture *capture;        /* the capture pipeline and its open dataset */
        struct session_runner *session; /* the scripted capture session, if any */
        struct scan *scan;              /* the continuous scan */
        struct workq *ds_worker;        /* runs dataset.* off the loop (datasets.c) */
        struct web *web;                /* the dashboard (--listen-http), or NULL */
        bool ds_busy;                   /* a dataset.open or close is running */
        uint64_t shutdown_deadline;     /* set once SIGTERM/SIGINT arrived */
        bool notify;      /* serving under systemd (NOTIFY_SOCKET): STATUS= kept current */
        char status[256]; /* the last STATUS= sent */
        /* the client (srv_req_client) that switched each switch on outside a session, 0 none:
         * switch i (rig.h: lamp i >= 0, laser k at RIG_SW_LASER(k)) at [RIG_MAX_LASERS + i] */
        uint64_t switch_owner[RIG_MAX_LASERS + RIG_MAX_LAMPS];
};

/* Loads the rig file, opens the rig, listens on the sockets systemd passed (socket
 * activation), else on socket_path (operator) and admin_path (admin). On a rig-file error the
 * message (file, line, key) is logged. Returns 0 or -errno. */
int manager_new(const char *rig_path, const char *socket_path, const char *admin_path,
                const char *data_dir, struct manager **ret);

/* Runs the loop until SIGTERM/SIGINT. Under systemd it sends READY=1 once serving,
 * WATCHDOG=1 from the loop (sd-event: between 1/2 and 3/4 of WATCHDOG_USEC), STATUS= when
 * what goniod does changes, and STOPPING=1 at the signal. */
int manager_run(struct manager *m);

/* Safe state, closes everything. NULL is a no-op; returns NULL. */
struct manager *manager_free(struct manager *m);

/* What goniod does when connection client closes (methods.c): the lasers and lamps it
 * switched on outside a session go off. For server_on_close; ud is the manager. */
void manager_client_gone(uint64_t client, void *ud);

/* The result of the status method (methods.c): the rig's status, the open dataset, the
 * storage. New reference. */
json_t *manager_status(struct manager *m);

/* Why the rig refused an operation at once with -errno r, for a reply (methods.c). */
const char *manager_refusal(const struct manager *m, int r);

/* Refuses req (answering it with -EBUSY and the reason; returns that) while a session or a
 * scan owns the rig; else returns 0 (methods.c). */
int manager_session_refuses(struct srv_req *req, struct manager *m);

/* device.get and device.set of the control protocol (settings.c, docs/protocol.md). */
int settings_get(struct srv_req *req, json_t *params, void *userdata);
int settings_set(struct srv_req *req, json_t *params, void *userdata);

/* The method table of the control protocol (methods.c). */
extern const struct srv_method manager_methods[];

/* Sends a notification to every client (params stolen). */
void manager_notify_json(struct manager *m, const char *method, json_t *params);

/* Turns a rig event into its protocol notification (rig_event_fn). */
void manager_on_rig_event(void *userdata, const struct rig_event *ev);
