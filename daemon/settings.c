/* settings.c - device.get and device.set of the control protocol (docs/protocol.md): the
 * settings of axes and cameras (rig_settings.c) read, and changed between sessions, each
 * change announced to every client with a setting.changed notification. */
#include <errno.h>
#include <math.h>
#include <string.h>

#include "manager.h"

#define KEYS(...) ((const char *const[]){__VA_ARGS__, NULL})

/* A device.set waiting for its axis's drive. */
struct setting_op {
        struct manager *m;
        struct srv_req *req;
        char device[RIG_NAME_MAX], setting[32];
        double value;
};

/* {device, class, settings} of the axis or camera named name. */
static json_t *device_settings(const struct manager *m, const char *name, const char *cls)
{
        return json_pack("{ssssso?}", "device", name, "class", cls, "settings",
                         rig_settings_json(m->rig, name));
}

/* Every axis and camera with its settings. */
static json_t *all_settings(const struct manager *m)
{
        json_t *a = json_array();

        for (size_t i = 0; i < m->rc->n_axes; i++)
                json_array_append_new(a, device_settings(m, m->rc->axes[i].name, "axis"));
        for (size_t i = 0; i < m->rc->n_cameras; i++)
                json_array_append_new(a, device_settings(m, m->rc->cameras[i].name, "camera"));
        return json_pack("{so}", "devices", a);
}

/* {device, setting, value, min, max, unit, limit} of s. */
static json_t *setting_json(const char *device, const struct rig_setting *s)
{
        return json_pack("{sssssfsfsfssss}", "device", device, "setting", s->name, "value",
                         s->value, "min", s->min, "max", s->max, "unit", s->unit, "limit",
                         s->limit);
}

int settings_get(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *device = NULL, *name = NULL;
        struct rig_setting s;
        char msg[256];
        int r;

        if ((r = srv_params_check(req, params, KEYS("device", "setting"))) < 0 ||
            (r = srv_param_str(req, params, "device", &device)) < 0 ||
            (r = srv_param_str(req, params, "setting", &name)) < 0)
                return r;
        if (!device && name)
                return srv_req_errmsg(req, -EINVAL, "param 'setting' needs 'device'");
        if (!device)
                return srv_reply(req, all_settings(m)), 0;
        if (name) {
                if ((r = rig_setting_get(m->rig, device, name, &s, msg, sizeof(msg))) < 0)
                        return srv_req_errmsg(req, r, "%s", msg);
                return srv_reply(req, setting_json(device, &s)), 0;
        }
        if (rig_axis_index(m->rig, device) < 0 && rig_camera_index(m->rig, device) < 0)
                return srv_req_errmsg(req, -ENOENT, "no axis or camera named '%s'", device);
        srv_reply(req, device_settings(m, device,
                                       rig_axis_index(m->rig, device) >= 0 ? "axis" : "camera"));
        return 0;
}

static void on_set(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct setting_op *o = userdata;
        json_t *res;

        if (result < 0)
                srv_fail(o->req, result, "%s.%s: %s", o->device, o->setting,
                         msg ?: strerror(-result));
        else {
                res = json_pack("{sssssf}", "device", o->device, "setting", o->setting, "value",
                                o->value);
                manager_notify_json(o->m, "setting.changed", json_incref(res));
                srv_reply(o->req, res);
        }
        free(o);
}

int settings_set(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *device = NULL, *name = NULL;
        double value = NAN;
        struct setting_op *o;
        char msg[256];
        int r;

        if ((r = srv_params_check(req, params, KEYS("device", "setting", "value"))) < 0 ||
            (r = srv_param_str(req, params, "device", &device)) < 0 ||
            (r = srv_param_str(req, params, "setting", &name)) < 0 ||
            (r = srv_param_double(req, params, "value", &value)) < 0)
                return r;
        if (!device || !name || isnan(value))
                return srv_req_errmsg(req, -EINVAL,
                                      "params 'device', 'setting' and 'value' are required");
        if ((r = manager_session_refuses(req, m)) < 0)
                return r;
        if (!(o = calloc(1, sizeof(*o))))
                return -ENOMEM;
        *o = (struct setting_op){.m = m, .req = req, .value = value};
        snprintf(o->device, sizeof(o->device), "%s", device);
        snprintf(o->setting, sizeof(o->setting), "%s", name);
        r = rig_setting_set(m->rig, device, name, value, on_set, o, msg, sizeof(msg));
        if (r < 0) {
                free(o);
                return srv_req_errmsg(req, r, "%s.%s: %s", device, name,
                                      msg[0] ? msg : manager_refusal(m, r));
        }
        return 0;
}
