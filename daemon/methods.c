/* methods.c - the methods of the control protocol (docs/protocol.md): each
 * checks its params, then starts the operation on the rig or the store and
 * answers when it is done (the dataset.* methods are in datasets.c). */
#include <errno.h>
#include <math.h>
#include <string.h>
#include <sys/statvfs.h>

#include "common/clock.h"
#include "common/log.h"
#include "calcopy.h"
#include "datasets.h"
#include "manager.h"
#include "protocol/proto.h"

#define KEYS(...) ((const char *const[]){__VA_ARGS__, NULL})

/* Completion of a rig operation that answers one request with a fixed result. */
struct op {
        struct srv_req *req;
        json_t *result;
        unsigned pending;
        int error;
        char msg[256];
        struct manager *m;
        json_t *(*build)(struct op *o); /* builds the result when all parts succeeded */
        int axes[RIG_MAX_AXES];
        int n_axes;
};

static struct op *op_new(struct srv_req *req, json_t *result)
{
        struct op *o = calloc(1, sizeof(*o));

        if (!o) {
                json_decref(result);
                return NULL;
        }
        o->req = req;
        o->result = result;
        return o;
}

/* Answers once the last part of a multi-part operation is done. */
static void op_part_done(struct op *o, int result, const char *msg)
{
        if (result < 0 && o->error == 0) {
                o->error = result;
                snprintf(o->msg, sizeof(o->msg), "%s", msg ? msg : strerror(-result));
        }
        if (--o->pending > 0)
                return;
        if (o->error < 0) {
                srv_fail(o->req, o->error, "%s", o->msg);
                json_decref(o->result);
        } else {
                if (o->build) {
                        json_decref(o->result);
                        o->result = o->build(o);
                }
                srv_reply(o->req, o->result);
        }
        free(o);
}

static void on_rig_done(struct rig *rig, int result, const char *msg, void *userdata)
{
        op_part_done(userdata, result, msg);
}

const char *manager_refusal(const struct manager *m, int r)
{
        switch (r) {
        case -ESTALE:
                return "the rig is in fault state (gonioctl fault clear, after fixing the cause)";
        case -EPERM:
                return "the axis is not homed (home first)";
        case -EBUSY:
                return rig_busy_reason(m->rig);
        case -ENODEV:
                return "the device is not available (it failed to open; see status)";
        default:
                return strerror(-r);
        }
}

/* Records an immediate refusal of one part of o. */
static void op_refused(struct op *o, int r, const char *device)
{
        char msg[256];

        snprintf(msg, sizeof(msg), "%s: %s", device, manager_refusal(o->m, r));
        op_part_done(o, r, msg);
}

/* Result listing the axes of o with their positions now. */
static json_t *axes_result(struct op *o)
{
        json_t *st = rig_status(o->m->rig), *axes = json_object_get(st, "axes"),
               *out = json_array();

        for (int i = 0; i < o->n_axes; i++) {
                json_t *a = json_array_get(axes, o->axes[i]);
                json_array_append_new(out, json_pack("{sOsO}", "name", json_object_get(a, "name"),
                                                     "position", json_object_get(a, "position")));
        }
        json_decref(st);
        return json_pack("{so}", "axes", out);
}

int manager_session_refuses(struct srv_req *req, struct manager *m)
{
        const char *why = session_busy_reason(m->session) ?: scan_busy_reason(m->scan);

        return why ? srv_req_errmsg(req, -EBUSY, "%s", why) : 0;
}

static int m_hello(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        long proto = PROTO_VERSION;
        int r;

        if ((r = srv_params_check(req, params, KEYS("client", "protocol", "token"))) < 0 ||
            (r = srv_param_int(req, params, "protocol", 0, 1000, &proto)) < 0)
                return r;
        if (proto != PROTO_VERSION)
                return srv_req_errmsg(req, -EPROTONOSUPPORT,
                                      "protocol %ld not supported (server speaks %d)", proto,
                                      PROTO_VERSION);
        srv_reply(req, json_pack("{sssssiss}", "server", "goniod", "version", "0.1.0", "protocol",
                                 PROTO_VERSION, "rig", m->rc->name));
        return 0;
}

/* The data root and the room on its filesystem (statvfs; null sizes when it fails). */
static json_t *storage_json(const char *root)
{
        struct statvfs v;

        if (statvfs(root, &v) < 0)
                return json_pack("{sssnsn}", "root", root, "free_bytes", "total_bytes");
        return json_pack("{sssIsI}", "root", root, "free_bytes",
                         (json_int_t)((uint64_t)v.f_bavail * v.f_frsize), "total_bytes",
                         (json_int_t)((uint64_t)v.f_blocks * v.f_frsize));
}

json_t *manager_status(struct manager *m)
{
        json_t *st = rig_status(m->rig);
        struct ds *d = capture_dataset(m->capture);

        if (strcmp(json_string_value(json_object_get(st, "state")), "idle") == 0 &&
            capture_in_flight(m->capture) > 0)
                json_object_set_new(st, "state", json_string("storing"));
        json_object_set_new(st, "dataset",
                            d ? json_pack("{sssssI}", "path", ds_path(d), "name",
                                          capture_dataset_name(m->capture), "count",
                                          (json_int_t)capture_dataset_count(m->capture))
                              : json_null());
        json_object_set_new(st, "storage", storage_json(m->data_dir));
        return st;
}

static int m_status(struct srv_req *req, json_t *params, void *userdata)
{
        srv_reply(req, manager_status(userdata));
        return 0;
}

static int m_describe(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;

        return calcopy_describe(m, req, rig_describe(m->rig));
}

static int m_home(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const struct rig_config *rc = m->rc;
        json_t *axes = json_object_get(params, "axes");
        size_t n = axes ? json_array_size(axes) : rc->n_axes;
        struct op *o;
        int r;

        if ((r = srv_params_check(req, params, KEYS("axes"))) < 0 ||
            (r = manager_session_refuses(req, m)) < 0)
                return r;
        if (axes && (!json_is_array(axes) || n > RIG_MAX_AXES))
                return srv_req_errmsg(req, -EINVAL, "param 'axes': expected a list of names");
        if (!(o = op_new(req, NULL)))
                return -ENOMEM;
        o->m = m;
        o->build = axes_result;
        for (size_t i = 0; i < n; i++) {
                const char *name =
                        axes ? json_string_value(json_array_get(axes, i)) : rc->axes[i].name;
                if (!name || (o->axes[i] = rig_axis_index(m->rig, name)) < 0) {
                        free(o);
                        return srv_req_errmsg(req, -ENOENT, "no axis named '%s'",
                                              name ? name : "?");
                }
        }
        o->n_axes = n;
        o->pending = n + 1;
        for (size_t i = 0; i < n; i++) {
                r = rig_home(m->rig, o->axes[i], on_rig_done, o);
                if (r < 0)
                        op_refused(o, r, rc->axes[o->axes[i]].name);
        }
        op_part_done(o, 0, NULL);
        return 0;
}

/* Result of a move: the axis and where it is now. */
static json_t *move_result(struct op *o)
{
        json_t *all = axes_result(o), *a = json_array_get(json_object_get(all, "axes"), 0);
        json_t *out = json_pack("{sOsO}", "axis", json_object_get(a, "name"), "position",
                                json_object_get(a, "position"));

        json_decref(all);
        return out;
}

/* Why a move of axis i was refused, with the limits where they are the reason. */
static const char *move_refusal(struct manager *m, int i, int r, char *buf, size_t len)
{
        const struct rig_axis_conf *c = &m->rc->axes[i];

        if (r != -ERANGE)
                return manager_refusal(m, r);
        snprintf(buf, len, "outside the soft limits [%g, %g] deg of '%s'", c->min_deg, c->max_deg,
                 c->name);
        return buf;
}

static int m_move(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *axis = NULL;
        double pos = NAN;
        bool relative = false, wait = true;
        char why[160];
        struct op *o;
        int i, r;

        if ((r = srv_params_check(req, params, KEYS("axis", "position", "relative", "wait"))) < 0 ||
            (r = srv_param_str(req, params, "axis", &axis)) < 0 ||
            (r = srv_param_double(req, params, "position", &pos)) < 0 ||
            (r = srv_param_bool(req, params, "relative", &relative)) < 0 ||
            (r = srv_param_bool(req, params, "wait", &wait)) < 0 ||
            (r = manager_session_refuses(req, m)) < 0)
                return r;
        if (!axis || isnan(pos))
                return srv_req_errmsg(req, -EINVAL, "params 'axis' and 'position' are required");
        if ((i = rig_axis_index(m->rig, axis)) < 0)
                return srv_req_errmsg(req, -ENOENT, "no axis named '%s'", axis);
        if (!(o = op_new(req, NULL)))
                return -ENOMEM;
        o->m = m;
        o->build = move_result;
        o->axes[0] = i;
        o->n_axes = 1;
        o->pending = 1;
        r = rig_move(m->rig, i, &pos, relative, wait ? on_rig_done : NULL, o);
        if (r < 0) {
                free(o);
                return srv_req_errmsg(req, r, "move %s to %g: %s", axis, pos,
                                      move_refusal(m, i, r, why, sizeof(why)));
        }
        if (!wait) {
                free(o);
                srv_reply(req, json_pack("{sssf}", "axis", axis, "target", pos));
        }
        return 0;
}

static int m_stop(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        json_t *names = json_array();
        int stopped[RIG_MAX_AXES];
        size_t n = rig_stop(m->rig, stopped);

        scan_cancel(m->scan);

        for (size_t i = 0; i < n; i++)
                json_array_append_new(names, json_string(m->rc->axes[stopped[i]].name));
        srv_reply(req, json_pack("{so}", "stopped", names));
        return 0;
}

static uint64_t *owner_of(struct manager *m, int i)
{
        return &m->switch_owner[RIG_MAX_LASERS + i]; /* laser k is i = -1 - k */
}

void manager_client_gone(uint64_t client, void *ud)
{
        struct manager *m = ud;

        for (int i = -(int)m->rc->n_lasers; i < (int)m->rc->n_lamps; i++) {
                const char *name = rig_switch_conf_of(m->rc, i)->name;
                if (*owner_of(m, i) != client)
                        continue;
                *owner_of(m, i) = 0;
                if (session_busy_reason(m->session) || scan_busy_reason(m->scan))
                        continue; /* a session has the rig now: it owns its switches */
                log_info("client gone: switching %s '%s' off", i < 0 ? "laser" : "lamp", name);
                if (rig_switch(m->rig, i, false, NULL, NULL) < 0) /* busy: max_on_s ends it */
                        log_warning("cannot switch '%s' off now: %s", name,
                                    rig_busy_reason(m->rig));
        }
}

/* Switches the n switches of indices first.. (a lamp, or lasers: RIG_SW_LASER) and answers
 * with {key: name, on, off_on_disconnect} once all are done; name lists them, comma-separated;
 * off_on_disconnect: they went on and go off when this client disconnects. */
static int switch_and_reply(struct srv_req *req, struct manager *m, int first, int n, bool on,
                            const char *key, const char *name)
{
        bool held = on;
        struct op *o;
        int r;

        if ((r = manager_session_refuses(req, m)) < 0)
                return r;
        for (int i = first; i < first + n; i++)
                held = held && rig_switch_conf_of(m->rc, i)->off_on_disconnect;
        if (!(o = op_new(req,
                         json_pack("{sssbsb}", key, name, "on", on, "off_on_disconnect", held))))
                return -ENOMEM;
        o->m = m;
        o->pending = n + 1;
        for (int i = first; i < first + n; i++) {
                r = rig_switch(m->rig, i, on, on_rig_done, o);
                if (r < 0)
                        op_refused(o, r, rig_switch_conf_of(m->rc, i)->name);
                else if (rig_switch_conf_of(m->rc, i)->off_on_disconnect)
                        *owner_of(m, i) = on ? srv_req_client(req) : 0;
        }
        op_part_done(o, 0, NULL);
        return 0;
}

static int m_lamp_set(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        json_t *lamp = json_object_get(params, "lamp");
        char name[32];
        bool on = false;
        int i, r;

        if ((r = srv_params_check(req, params, KEYS("lamp", "on"))) < 0 ||
            (r = srv_param_bool(req, params, "on", &on)) < 0)
                return r;
        if (json_is_integer(lamp))
                snprintf(name, sizeof(name), "%lld", (long long)json_integer_value(lamp));
        else if (json_is_string(lamp))
                snprintf(name, sizeof(name), "%s", json_string_value(lamp));
        else
                return srv_req_errmsg(req, -EINVAL, "param 'lamp': expected a name or an index");
        if (!json_is_boolean(json_object_get(params, "on")))
                return srv_req_errmsg(req, -EINVAL, "param 'on' is required");
        if ((i = rig_lamp_index(m->rig, name)) < 0)
                return srv_req_errmsg(req, -ENOENT, "no lamp '%s'", name);
        return switch_and_reply(req, m, i, 1, on, "lamp", m->rc->lamps[i].name);
}

/* laser.set {laser?, on}: the laser named, or every laser of the rig. */
static int m_laser_set(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        json_t *laser = json_object_get(params, "laser");
        const char *names[RIG_MAX_LASERS];
        char list[RIG_MAX_LASERS * RIG_NAME_MAX];
        bool on = false;
        int r, k = 0, n = m->rc->n_lasers;

        if ((r = srv_params_check(req, params, KEYS("laser", "on"))) < 0 ||
            (r = srv_param_bool(req, params, "on", &on)) < 0)
                return r;
        if (r == 0)
                return srv_req_errmsg(req, -EINVAL, "param 'on' is required");
        if (laser && !json_is_string(laser))
                return srv_req_errmsg(req, -EINVAL, "param 'laser': expected a name");
        if (n == 0)
                return srv_req_errmsg(req, -ENOENT, "this rig has no laser");
        if (laser && (k = rigconf_laser(m->rc, json_string_value(laser))) < 0)
                return srv_req_errmsg(req, -ENOENT, "no laser '%s'", json_string_value(laser));
        n = laser ? 1 : n;
        for (int i = 0; i < n; i++)
                names[i] = m->rc->lasers[k + i].name;
        (void)gn_name_list((UINT32_C(1) << n) - 1, names, n, list, sizeof(list));
        return switch_and_reply(req, m, RIG_SW_LASER(k + n - 1), n, on, "laser", list);
}

static int m_fault_clear(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        struct op *o = op_new(req, json_object());
        int r;

        if (!o)
                return -ENOMEM;
        o->pending = 1;
        r = rig_clear_fault(m->rig, on_rig_done, o);
        if (r < 0) {
                json_decref(o->result);
                free(o);
                return srv_req_errmsg(req, r, "a fault clear is already running");
        }
        return 0;
}

static int m_fault_override(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        int r = srv_params_check(req, params, KEYS(NULL));

        if (r >= 0 && (r = rig_override_fault(m->rig)) == -EBUSY)
                return srv_req_errmsg(req, r,
                                      "the rig is still reaching its safe state or clearing the "
                                      "fault; retry");
        if (r < 0)
                return r;
        srv_reply(req, NULL);
        return 0;
}

/* Answers a capture: every row stored, or an error whose data lists what was stored and
 * what failed, so that a client retries only the cameras that failed. */
static void on_captured(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct srv_req *req = userdata;
        json_t *stored = json_array(), *failed = json_array();
        const struct capture_shot *first = NULL;

        for (size_t i = 0; i < res->n_shots; i++) {
                const struct capture_shot *s = &res->shots[i];
                if (s->result >= 0) {
                        json_array_append_new(stored, datasets_row_json(&s->row));
                        continue;
                }
                first = first ? first : s;
                json_array_append_new(failed,
                                      json_pack("{sssiss}", "camera", s->row.camera, "code",
                                                proto_errno_to_code(s->result), "message", s->msg));
        }
        if (!first) {
                json_decref(failed);
                return srv_reply(req, json_pack("{so}", "captures", stored));
        }
        srv_fail_data(req, first->result, json_pack("{soso}", "stored", stored, "failed", failed),
                      "%s (%zu of %zu cameras stored)", first->msg, json_array_size(stored),
                      res->n_shots);
}

/* Reads exposure, gain and bits; their ranges are each camera's (rig_check_camera_request). */
static int read_cam_request(struct srv_req *req, json_t *params, struct cam_request *cr)
{
        long exposure = 0, bits = 0;
        double gain = 0;
        int r;

        if ((r = srv_param_int(req, params, "exposure_us", 1, INT32_MAX, &exposure)) < 0 ||
            (r = srv_param_double(req, params, "gain", &gain)) < 0 ||
            (r = srv_param_int(req, params, "bits", 8, 16, &bits)) < 0)
                return r;
        if (!isfinite(gain) || gain < 0)
                return srv_req_errmsg(req, -EINVAL, "param 'gain': must be a positive number");
        *cr = (struct cam_request){.exposure_us = exposure, .gain = gain, .bits = bits};
        return 0;
}

/* Checks cr against every camera of cams; answers with the first camera's objection. */
static int check_cameras(struct srv_req *req, struct manager *m, const int *cams, size_t n,
                         const struct cam_request *cr)
{
        char msg[256];
        int r;

        for (size_t i = 0; i < n; i++)
                if ((r = rig_check_camera_request(m->rig, cams[i], cr, msg, sizeof(msg))) < 0)
                        return srv_req_errmsg(req, r, "camera '%s': %s",
                                              m->rc->cameras[cams[i]].name, msg);
        return 0;
}

static int m_capture(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *camera = NULL;
        struct cam_request cr;
        int cams[RIG_MAX_CAMERAS];
        size_t n = 0;
        int r;

        if ((r = srv_params_check(req, params, KEYS("camera", "exposure_us", "gain", "bits"))) <
                    0 ||
            (r = srv_param_str(req, params, "camera", &camera)) < 0 ||
            (r = read_cam_request(req, params, &cr)) < 0 ||
            (r = manager_session_refuses(req, m)) < 0)
                return r;
        if (camera && (cams[n++] = rig_camera_index(m->rig, camera)) < 0)
                return srv_req_errmsg(req, -ENOENT, "no camera named '%s'", camera);
        for (size_t i = 0; !camera && i < m->rc->n_cameras; i++)
                cams[n++] = i;
        if (n == 0)
                return srv_req_errmsg(req, -ENOENT, "this rig has no camera");
        if ((r = check_cameras(req, m, cams, n, &cr)) < 0)
                return r;
        if (!capture_dataset(m->capture))
                return srv_req_errmsg(req, -ESTALE, "no dataset is open (dataset.open first)");
        r = capture_take(m->capture, cams, n, &cr, NULL, on_captured, req);
        if (r < 0)
                return srv_req_errmsg(req, r, "capture refused: %s", manager_refusal(m, r));
        return 0;
}

/* ---- scan.continuous ---- */

/* Refuses a session while a scan owns the rig. */
static int scan_refuses(struct srv_req *req, struct manager *m)
{
        const char *why = scan_busy_reason(m->scan);

        return why ? srv_req_errmsg(req, -EBUSY, "%s", why) : 0;
}

/* Reads the scan's camera, angles and controls; the dataset must be the open one. */
static int read_scan_params(struct srv_req *req, json_t *params, struct manager *m,
                            struct scan_params *p)
{
        const char *dataset = NULL, *camera = NULL, *open = capture_dataset_name(m->capture);
        int r;

        *p = (struct scan_params){.cam = 0, .from = 0, .to = 360, .step = 0.45};
        if ((r = srv_params_check(req, params,
                                  KEYS("dataset", "camera", "from", "to", "step", "exposure_us",
                                       "gain", "bits"))) < 0 ||
            (r = srv_param_str(req, params, "dataset", &dataset)) < 0 ||
            (r = srv_param_str(req, params, "camera", &camera)) < 0 ||
            (r = srv_param_double(req, params, "from", &p->from)) < 0 ||
            (r = srv_param_double(req, params, "to", &p->to)) < 0 ||
            (r = srv_param_double(req, params, "step", &p->step)) < 0 ||
            (r = read_cam_request(req, params, &p->req)) < 0)
                return r;
        if (!dataset)
                return srv_req_errmsg(req, -EINVAL, "param 'dataset' is required");
        if (!open || strcmp(open, dataset) != 0)
                return srv_req_errmsg(req, -ESTALE,
                                      "dataset '%s' is not the open dataset "
                                      "(dataset.open it first)",
                                      dataset);
        if (m->rc->n_cameras == 0)
                return srv_req_errmsg(req, -ENOENT, "this rig has no camera");
        if (camera && (p->cam = rig_camera_index(m->rig, camera)) < 0)
                return srv_req_errmsg(req, -ENOENT, "no camera named '%s'", camera);
        return check_cameras(req, m, &p->cam, 1, &p->req);
}

static int m_scan_continuous(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        struct scan_params p;
        char msg[256];
        int r;

        if ((r = read_scan_params(req, params, m, &p)) < 0)
                return r;
        r = scan_start(m->scan, req, &p, msg, sizeof(msg));
        return r < 0 ? srv_req_errmsg(req, r, "%s", msg) : 0;
}

/* ---- session.* ---- */

/* Reads the session file's name and text (gonioctl sends the file's bytes). */
static int read_session_file(struct srv_req *req, json_t *params, const char **file,
                             const char **text)
{
        int r;

        if ((r = srv_params_check(req, params, KEYS("file", "text"))) < 0 ||
            (r = srv_param_str(req, params, "file", file)) < 0 ||
            (r = srv_param_str(req, params, "text", text)) < 0)
                return r;
        if (!*text)
                return srv_req_errmsg(req, -EINVAL, "param 'text' (the session file) is required");
        if (!*file)
                *file = "session";
        return 0;
}

static int m_session_plan(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *file = NULL, *text = NULL;
        char msg[512];
        json_t *plan;
        int r;

        if ((r = read_session_file(req, params, &file, &text)) < 0)
                return r;
        plan = session_plan(m->session, file, text, &r, msg, sizeof(msg));
        if (!plan)
                return srv_req_errmsg(req, r, "%s", msg);
        srv_reply(req, plan);
        return 0;
}

/* Answers session.run or session.resume once the session runs (or could not). */
static void on_session_started(struct manager *m, int result, const char *msg, json_t *info,
                               void *userdata)
{
        if (result < 0) {
                json_decref(info);
                return srv_fail(userdata, result, "%s", msg);
        }
        srv_reply(userdata, info);
}

static int m_session_run(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *file = NULL, *text = NULL;
        char msg[512];
        int r;

        if ((r = read_session_file(req, params, &file, &text)) < 0 ||
            (r = scan_refuses(req, m)) < 0)
                return r;
        r = session_start(m->session, file, text, on_session_started, req, msg, sizeof(msg));
        return r < 0 ? srv_req_errmsg(req, r, "%s", msg) : 0;
}

static int m_session_resume(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *dataset = NULL;
        char msg[512];
        int r;

        if ((r = srv_params_check(req, params, KEYS("dataset"))) < 0 ||
            (r = srv_param_str(req, params, "dataset", &dataset)) < 0 ||
            (r = scan_refuses(req, m)) < 0)
                return r;
        r = session_resume(m->session, dataset, on_session_started, req, msg, sizeof(msg));
        return r < 0 ? srv_req_errmsg(req, r, "%s", msg) : 0;
}

/* session.pause and session.abort: answered with the status at once. */
static int session_control(struct srv_req *req, json_t *params, struct manager *m,
                           int (*fn)(struct session_runner *, char *, size_t))
{
        char msg[256];
        int r;

        if ((r = srv_params_check(req, params, KEYS(NULL))) < 0)
                return r;
        if ((r = fn(m->session, msg, sizeof(msg))) < 0)
                return srv_req_errmsg(req, r, "%s", msg);
        srv_reply(req, session_status(m->session));
        return 0;
}

static int m_session_pause(struct srv_req *req, json_t *params, void *userdata)
{
        return session_control(req, params, userdata, session_pause);
}

/* session.abort: the loaded session, else (after a restart) an unfinished one in the index. */
static int m_session_abort(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *dataset = NULL;
        char msg[512];
        int r;

        if (session_active(m->session))
                return session_control(req, params, m, session_abort);
        if ((r = srv_params_check(req, params, KEYS("dataset"))) < 0 ||
            (r = srv_param_str(req, params, "dataset", &dataset)) < 0)
                return r;
        r = session_abandon(m->session, dataset, on_session_started, req, msg, sizeof(msg));
        return r < 0 ? srv_req_errmsg(req, r, "%s", msg) : 0;
}

static int m_session_status(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        int r;

        if ((r = srv_params_check(req, params, KEYS(NULL))) < 0)
                return r;
        srv_reply(req, session_status(m->session));
        return 0;
}

const struct srv_method manager_methods[] = {
        {"hello", m_hello},
        {"status", m_status},
        {"describe", m_describe},
        {"home", m_home},
        {"move", m_move},
        {"stop", m_stop},
        {"lamp.set", m_lamp_set},
        {"laser.set", m_laser_set},
        {"capture", m_capture},
        {"device.get", settings_get},
        {"device.set", settings_set},
        {"dataset.open", datasets_open},
        {"dataset.close", datasets_close},
        {"dataset.list", datasets_list},
        {"dataset.info", datasets_info},
        {"dataset.check", datasets_check},
        {"fault.clear", m_fault_clear},
        {"fault.override", m_fault_override, .admin = true},
        {"session.plan", m_session_plan},
        {"session.run", m_session_run},
        {"session.resume", m_session_resume},
        {"session.pause", m_session_pause},
        {"session.abort", m_session_abort},
        {"session.status", m_session_status},
        {"scan.continuous", m_scan_continuous},
        {NULL, NULL},
};
