/* rig_json.c - the rig's status and describe objects of the control protocol. */
#include "drivers/registry.h"
#include "rig_internal.h"

static json_t *axis_status(const struct rig_axis *a)
{
        const struct rig_axis_conf *c = a->ax->conf;

        return json_pack(
                "{sssfsbsbsbsbsbsbsisfsfsbss?}", "name", c->name, "position", a->st.position_deg,
                "moving", a->op != AX_IDLE || (a->open && a->st.moving), "done", a->op == AX_IDLE,
                "missed", a->missed, "homed", a->st.homed || c->absolute_encoder, "fault",
                a->st.fault, "open", a->open, "fault_code", a->st.fault_code, "min", c->min_deg,
                "max", c->max_deg, "continuous", c->continuous, "role", gn_role_name(c->role));
}

static json_t *switch_status(const struct rig_switch *s)
{
        return json_pack("{sssbsb}", "name", s->sw->conf->name, "on", s->sw->on, "open", s->open);
}

json_t *rig_status(const struct rig *rig)
{
        const struct rig_config *rc = rig->rc;
        json_t *axes = json_array(), *lamps = json_array(), *lasers = json_array(),
               *cams = json_array();
        bool homed = rc->n_axes > 0;

        for (size_t i = 0; i < rc->n_axes; i++) {
                json_array_append_new(axes, axis_status(&rig->axes[i]));
                homed = homed && rig->axes[i].st.homed;
        }
        for (size_t i = 0; i < rc->n_lamps; i++)
                json_array_append_new(lamps, switch_status(&rig->lamps[i]));
        for (size_t i = 0; i < rc->n_lasers; i++)
                json_array_append_new(lasers, switch_status(&rig->lasers[i]));
        for (size_t i = 0; i < rc->n_cameras; i++)
                json_array_append_new(
                        cams, json_pack("{sssisisisb}", "name", rc->cameras[i].name, "width",
                                        rc->cameras[i].width, "height", rc->cameras[i].height,
                                        "bits", rc->cameras[i].bits, "open", rig->cam_open[i]));
        return json_pack("{sssbsosososososo}", "state", rig_state(rig), "homed", homed, "axes",
                         axes, "lamps", lamps, "lasers", lasers, "laser",
                         rc->n_lasers ? switch_status(&rig->lasers[0]) : json_null(), "cameras",
                         cams, "fault",
                         rig->fault ? json_pack("{ssss}", "device", rig->fault_device, "message",
                                                rig->fault_msg)
                                    : json_null());
}

static json_t *opts_json(const struct opt_desc *opts, int n)
{
        json_t *a = json_array();

        for (int i = 0; i < n; i++)
                json_array_append_new(
                        a, json_pack("{sssbsbss?sfsf}", "name", opt_key_name(opts[i].key), "get",
                                     (opts[i].flags & OPT_GET) != 0, "set",
                                     (opts[i].flags & OPT_SET) != 0, "unit", opts[i].unit, "min",
                                     opts[i].min, "max", opts[i].max));
        return a;
}

static json_t *device_json(const char *cls, const char *name, const char *backend, const char *bus,
                           const struct opt_desc *opts, int n, json_t *config)
{
        return json_pack("{sssssssssoso}", "class", cls, "name", name, "backend", backend, "bus",
                         bus, "options", opts_json(opts, n), "config", config);
}

/* device_json of an axis or a camera, with its settings (rig_settings.c). */
static json_t *settable_json(const struct rig *rig, const char *cls, const char *name,
                             const char *backend, const char *bus, const struct opt_desc *opts,
                             int n, json_t *config)
{
        json_t *d = device_json(cls, name, backend, bus, opts, n, config);

        json_object_set_new(d, "settings", rig_settings_json(rig, name));
        return d;
}

/* What the rig file sets for axis c (its limits, speeds and motion semantics, defaults
 * filled in). */
static json_t *axis_config(const struct rig_axis_conf *c)
{
        return json_pack("{ss?sbsfsfsfsfsfsisfsfsisbsisi}", "role",
                         c->role >= 0 ? gn_role_name(c->role) : NULL, "continuous", c->continuous,
                         "min", c->min_deg, "max", c->max_deg, "max_speed", c->max_speed, "accel",
                         c->accel, "max_accel", axis_max_accel(c), "settle_ms", c->settle_ms,
                         "backlash", c->backlash_deg, "deadband", c->deadband_deg, "move_retries",
                         c->move_retries, "absolute_encoder", c->absolute_encoder, "direction",
                         c->direction, "move_timeout_ms", c->move_timeout_ms);
}

static json_t *switch_config(const struct rig_switch_conf *c)
{
        json_t *o = json_pack("{sisfsb}", "warmup_ms", c->warmup_ms, "max_on_s", c->max_on_s,
                              "off_on_disconnect", c->off_on_disconnect);

        if (c->kind == RIG_SWITCH_LAMP)
                json_object_update_new(o, json_pack("{sfsfsfsf}", "elevation", c->elevation_deg,
                                                    "radius", c->radius_mm, "azimuth",
                                                    c->azimuth_deg, "intensity", c->intensity));
        else
                json_object_update_new(o, json_pack("{sfsf}", "azimuth", c->laser_azimuth_deg,
                                                    "width", c->laser_width_mm));
        return o;
}

static json_t *camera_config(const struct rig_camera_conf *c)
{
        return json_pack("{sisisisfsisfsfsfsfsfsisf}", "width", c->width, "height", c->height,
                         "bits", c->bits, "gain", c->gain, "exposure_us", c->exposure_us,
                         "frame_rate", c->frame_rate, "fx", c->fx, "fy", c->fy, "cx", c->cx, "cy",
                         c->cy, "max_exposure_us", c->max_exposure_us, "max_gain", c->max_gain);
}

json_t *rig_describe(const struct rig *rig)
{
        const struct rig_config *rc = rig->rc;
        json_t *devs = json_array();

        for (size_t i = 0; i < rc->n_axes; i++) {
                const struct axis *ax = rig->axes[i].ax;
                json_array_append_new(devs,
                                      settable_json(rig, "axis", rc->axes[i].name, ax->ops->name,
                                                    rc->axes[i].bus, ax->ops->opts, ax->ops->n_opts,
                                                    axis_config(&rc->axes[i])));
        }
        for (size_t i = 0; i < rc->n_lamps + rc->n_lasers; i++) {
                const struct sw *s =
                        i < rc->n_lamps ? rig->lamps[i].sw : rig->lasers[i - rc->n_lamps].sw;
                json_array_append_new(devs,
                                      device_json(i < rc->n_lamps ? "lamp" : "laser", s->conf->name,
                                                  s->ops->name, s->conf->bus, s->ops->opts,
                                                  s->ops->n_opts, switch_config(s->conf)));
        }
        for (size_t i = 0; i < rc->n_cameras; i++) {
                const struct cam *c = rig->cams[i];
                int n;
                const struct opt_desc *opts = cam_opts(c, &n);

                json_array_append_new(devs,
                                      settable_json(rig, "camera", c->conf->name, c->ops->name,
                                                    c->conf->bus, opts, n, camera_config(c->conf)));
        }
        return json_pack("{ssso}", "rig", rc->name, "devices", devs);
}
