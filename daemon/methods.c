/* methods.c - the methods of the control protocol (docs/protocol.md): each
 * checks its params, then starts the operation on the rig or the store and
 * answers when it is done (the dataset.* methods are in datasets.c). */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "common/clock.h"
#include "common/log.h"
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

/* Why the rig refused an operation at once. */
static const char *refusal(int r)
{
        switch (r) {
        case -ESTALE:
                return "the rig is in fault state (gonioctl fault clear, after fixing the cause)";
        case -EPERM:
                return "the axis is not homed (home first)";
        case -EBUSY:
                return "busy: an axis is moving";
        case -ENODEV:
                return "the device is not available (it failed to open)";
        case -ERANGE:
                return "target outside the soft limits";
        default:
                return strerror(-r);
        }
}

/* Records an immediate refusal of one part of o. */
static void op_refused(struct op *o, int r, const char *device)
{
        char msg[256];

        snprintf(msg, sizeof(msg), "%s: %s", device, refusal(r));
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

static int m_hello(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        long proto = PROTO_VERSION;
        int r;

        if ((r = srv_params_check(req, params, KEYS("client", "protocol"))) < 0 ||
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

static int m_status(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        json_t *st = rig_status(m->rig);

        json_object_set_new(st, "dataset",
                            m->ds ? json_pack("{sssssI}", "path", ds_path(m->ds), "name",
                                              m->ds_name, "count", (json_int_t)m->ds_count)
                                  : json_null());
        srv_reply(req, st);
        return 0;
}

static int m_describe(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;

        srv_reply(req, rig_describe(m->rig));
        return 0;
}

static int m_home(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const struct rig_config *rc = m->rc;
        json_t *axes = json_object_get(params, "axes");
        size_t n = axes ? json_array_size(axes) : rc->n_axes;
        struct op *o;
        int r;

        if ((r = srv_params_check(req, params, KEYS("axes"))) < 0)
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

static int m_move(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *axis = NULL;
        double pos = NAN;
        bool relative = false, wait = true;
        struct op *o;
        int i, r;

        if ((r = srv_params_check(req, params, KEYS("axis", "position", "relative", "wait"))) < 0 ||
            (r = srv_param_str(req, params, "axis", &axis)) < 0 ||
            (r = srv_param_double(req, params, "position", &pos)) < 0 ||
            (r = srv_param_bool(req, params, "relative", &relative)) < 0 ||
            (r = srv_param_bool(req, params, "wait", &wait)) < 0)
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
                return srv_req_errmsg(req, r, "move %s to %g: %s", axis, pos, refusal(r));
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

        rig_stop(m->rig, names);
        srv_reply(req, json_pack("{so}", "stopped", names));
        return 0;
}

/* Switches lamp i (or the laser, i < 0) and answers with {key: name, on}. */
static int switch_and_reply(struct srv_req *req, struct manager *m, int i, bool on, const char *key,
                            const char *name)
{
        struct op *o = op_new(req, json_pack("{sssb}", key, name, "on", on));
        int r;

        if (!o)
                return -ENOMEM;
        o->pending = 1;
        r = rig_switch(m->rig, i, on, on_rig_done, o);
        if (r < 0) {
                json_decref(o->result);
                free(o);
                return srv_req_errmsg(req, r, "%s: %s", name, refusal(r));
        }
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
        return switch_and_reply(req, m, i, on, "lamp", m->rc->lamps[i].name);
}

static int m_laser_set(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        bool on = false;
        int r;

        if ((r = srv_params_check(req, params, KEYS("on"))) < 0 ||
            (r = srv_param_bool(req, params, "on", &on)) < 0)
                return r;
        if (r == 0)
                return srv_req_errmsg(req, -EINVAL, "param 'on' is required");
        if (!m->rc->has_laser)
                return srv_req_errmsg(req, -ENOENT, "this rig has no laser");
        return switch_and_reply(req, m, -1, on, "laser", m->rc->laser.name);
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

/* One camera's part of a capture request. */
struct shot {
        struct op *o;
        struct manager *m;
        int cam;
        uint64_t t_request_ns;
};

static void on_stored(int result, const struct ds_capture *c, const char *error, void *userdata)
{
        struct shot *s = userdata;
        char msg[300] = "the store was canceled";

        if (result >= 0) {
                s->m->ds_count++;
                json_array_append_new(json_object_get(s->o->result, "captures"),
                                      datasets_row_json(c));
                manager_notify(s->m, "capture.stored",
                               json_pack("{sIssssss}", "id", (json_int_t)c->id, "camera", c->camera,
                                         "file", c->file, "sha256", c->sha256));
        } else if (result != -ECANCELED) {
                snprintf(msg, sizeof(msg), "storing the frame of '%s' failed: %s", c->camera,
                         error);
                rig_fault(s->m->rig, "dataset", result, "%s", msg);
        }
        op_part_done(s->o, result, result < 0 ? msg : NULL);
        free(s);
}

/* The row's pose and lamps from a rig snapshot (lamp bits by rig-file index). */
static void snapshot_pose(struct rig *rig, const struct rig_snapshot *snap, struct ds_capture *c)
{
        char names[sizeof(snap->lamps)], *save = NULL;

        c->pose = gn_pose_none();
        c->pose.deg[GN_ROLE_TURNTABLE] = snap->turntable_deg;
        c->pose.deg[GN_ROLE_LIGHT_ARM] = snap->light_arm_deg;
        c->pose.deg[GN_ROLE_CAMERA_ARM] = snap->camera_arm_deg;
        c->pose.laser = snap->laser;
        snprintf(c->lamps, sizeof(c->lamps), "%s", snap->lamps);
        snprintf(names, sizeof(names), "%s", snap->lamps);
        for (char *t = strtok_r(names, ",", &save); t; t = strtok_r(NULL, ",", &save)) {
                int i = rig_lamp_index(rig, t);
                if (i >= 0 && i < GN_POSE_MAX_LAMPS)
                        c->pose.lamps |= UINT32_C(1) << i;
        }
}

static void on_frame(struct rig *rig, int result, const char *msg, struct gn_frame *frame,
                     void *userdata)
{
        struct shot *s = userdata;
        struct rig_snapshot snap;
        struct ds_capture c = {.t_request_ns = s->t_request_ns};
        int r = result;

        if (r >= 0 && !s->m->pool)
                r = -ESTALE, msg = "the dataset was closed during the capture";
        if (r >= 0) {
                rig_snapshot(rig, &snap);
                snapshot_pose(rig, &snap, &c);
                snprintf(c.camera, sizeof(c.camera), "%s", s->m->rc->cameras[s->cam].name);
                c.exposure_us = frame->exposure_us;
                c.gain = frame->gain;
                c.t_exposure_ns = frame->timestamp_ns;
                r = ds_pool_store(s->m->pool, frame, &c, on_stored, s);
                if (r >= 0)
                        return;
                msg = r == -EAGAIN ? "the storage queue is full" : strerror(-r);
        }
        op_part_done(s->o, r, msg);
        free(s);
}

static int read_cam_request(struct srv_req *req, json_t *params, struct cam_request *cr)
{
        long exposure = 0, bits = 0;
        double gain = 0;
        int r;

        if ((r = srv_param_int(req, params, "exposure_us", 1, 60000000, &exposure)) < 0 ||
            (r = srv_param_double(req, params, "gain", &gain)) < 0 ||
            (r = srv_param_int(req, params, "bits", 8, 16, &bits)) < 0)
                return r;
        if (bits && bits != 8 && bits != 16)
                return srv_req_errmsg(req, -EINVAL, "param 'bits': must be 8 or 16");
        if (gain < 0 || gain > 1000)
                return srv_req_errmsg(req, -EINVAL, "param 'gain': must be in [0, 1000]");
        *cr = (struct cam_request){.exposure_us = exposure, .gain = gain, .bits = bits};
        return 0;
}

static int m_capture(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *camera = NULL;
        struct cam_request cr;
        int first = 0, last = m->rc->n_cameras, r;
        struct op *o;

        if ((r = srv_params_check(req, params, KEYS("camera", "exposure_us", "gain", "bits"))) <
                    0 ||
            (r = srv_param_str(req, params, "camera", &camera)) < 0 ||
            (r = read_cam_request(req, params, &cr)) < 0)
                return r;
        if (!m->pool)
                return srv_req_errmsg(req, -ESTALE, "no dataset is open (dataset.open first)");
        if (camera && (first = rig_camera_index(m->rig, camera)) < 0)
                return srv_req_errmsg(req, -ENOENT, "no camera named '%s'", camera);
        if (camera)
                last = first + 1;
        if (!(o = op_new(req, json_pack("{s[]}", "captures"))))
                return -ENOMEM;
        o->pending = last - first + 1;
        for (int i = first; i < last; i++) {
                struct shot *s = calloc(1, sizeof(*s));
                if (!s) {
                        op_part_done(o, -ENOMEM, NULL);
                        continue;
                }
                *s = (struct shot){.o = o, .m = m, .cam = i, .t_request_ns = gn_realtime_ns()};
                r = rig_capture(m->rig, i, &cr, on_frame, s);
                if (r < 0) {
                        free(s);
                        op_refused(o, r, m->rc->cameras[i].name);
                }
        }
        op_part_done(o, 0, NULL);
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
        {"dataset.open", datasets_open},
        {"dataset.close", datasets_close},
        {"dataset.list", datasets_list},
        {"dataset.info", datasets_info},
        {"fault.clear", m_fault_clear},
        {NULL, NULL},
};
