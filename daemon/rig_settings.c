/* rig_settings.c - the device settings of the rig (docs/goniod.md, "Settings"): an axis's
 * speed and acceleration, a camera's default exposure and gain. A table says, per setting,
 * its device class, its unit, how to read its value and range and how to apply it; the range
 * comes from the rig file (max_speed, max_accel, max_exposure_us, max_gain) and, for a
 * camera, its driver's option table. An axis's rates go to its drive through a J_RATES job on
 * its bus worker; a camera's defaults fill the 0s of the following requests
 * (rig_camera_request), which every backend applies per capture. Loop thread. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <string.h>

#include "rig_internal.h"

#define RATE_MIN 0.1 /* deg/s, deg/s^2: the rig file's least max_speed and accel */

struct desc {
        const char *name, *unit;
        enum rig_class cls;
        /* value, min, max and limit of the setting of device i into s */
        void (*read)(const struct rig *rig, int i, struct rig_setting *s);
        int (*apply)(struct rig *rig, int i, double v, rig_done_fn done, void *ud);
};

static void read_speed(const struct rig *rig, int i, struct rig_setting *s)
{
        s->value = rig->axes[i].speed_setting;
        s->max = rig->rc->axes[i].max_speed;
        s->limit = "max_speed";
}

static void read_accel(const struct rig *rig, int i, struct rig_setting *s)
{
        s->value = rig->axes[i].accel_setting;
        s->max = axis_max_accel(&rig->rc->axes[i]);
        s->limit = "max_accel";
}

/* The range of control key of camera i: its driver's, within the rig file's max (rig_max > 0). */
static void camera_range(const struct rig *rig, int i, enum opt_key key, double rig_max,
                         const char *rig_key, struct rig_setting *s)
{
        int n = 0;
        const struct opt_desc *opts = cam_opts(rig->cams[i], &n), *o = opt_find(opts, n, key);

        s->min = o ? o->min : NAN;
        s->max = o ? o->max : NAN;
        s->limit = "the driver's range";
        if (o && rig_max > 0 && rig_max < s->max) {
                s->max = rig_max;
                s->limit = rig_key;
        }
}

static void read_exposure(const struct rig *rig, int i, struct rig_setting *s)
{
        const struct rig_camera_conf *c = &rig->rc->cameras[i];

        s->value = rig->cam_defaults[i].exposure_us ?: c->exposure_us;
        camera_range(rig, i, OPT_EXPOSURE, c->max_exposure_us, "max_exposure_us", s);
}

static void read_gain(const struct rig *rig, int i, struct rig_setting *s)
{
        const struct rig_camera_conf *c = &rig->rc->cameras[i];

        s->value = rig->cam_defaults[i].gain > 0 ? rig->cam_defaults[i].gain : c->gain;
        camera_range(rig, i, OPT_GAIN, c->max_gain, "max_gain", s);
}

/* Queues a J_RATES job writing speed and accel to axis i's drive; done follows. */
static int apply_rates(struct rig *rig, int i, double speed, double accel, rig_done_fn done,
                       void *ud)
{
        struct rig_axis *a = &rig->axes[i];
        struct job *j;

        if (rig->closing)
                return -ESHUTDOWN;
        if (rig->fault)
                return -ESTALE;
        if (a->op != AX_IDLE)
                return snprintf(rig->busy, sizeof(rig->busy), "axis '%s' is moving",
                                a->ax->conf->name),
                       -EBUSY;
        if (!a->open)
                return -ENODEV;
        if (!(j = calloc(1, sizeof(*j))))
                return -ENOMEM;
        *j = (struct job){.rig = rig,
                          .kind = J_RATES,
                          .idx = i,
                          .speed = speed,
                          .accel = accel,
                          .done = done,
                          .ud = ud};
        return rig_submit(j, false);
}

static int apply_speed(struct rig *rig, int i, double v, rig_done_fn done, void *ud)
{
        return apply_rates(rig, i, v, rig->axes[i].accel_setting, done, ud);
}

static int apply_accel(struct rig *rig, int i, double v, rig_done_fn done, void *ud)
{
        return apply_rates(rig, i, rig->axes[i].speed_setting, v, done, ud);
}

static int apply_exposure(struct rig *rig, int i, double v, rig_done_fn done, void *ud)
{
        rig->cam_defaults[i].exposure_us = (int)lround(v);
        done(rig, 0, NULL, ud);
        return 0;
}

static int apply_gain(struct rig *rig, int i, double v, rig_done_fn done, void *ud)
{
        rig->cam_defaults[i].gain = v;
        done(rig, 0, NULL, ud);
        return 0;
}

static const struct desc settings[] = {
        {"speed", "deg/s", RIG_CLASS_AXIS, read_speed, apply_speed},
        {"accel", "deg/s^2", RIG_CLASS_AXIS, read_accel, apply_accel},
        {"exposure_us", "us", RIG_CLASS_CAMERA, read_exposure, apply_exposure},
        {"gain", "", RIG_CLASS_CAMERA, read_gain, apply_gain},
};

/* The class and index of the axis or camera named device, or -ENOENT. */
static int find_device(const struct rig *rig, const char *device, enum rig_class *cls)
{
        int i = rig_axis_index(rig, device);

        *cls = RIG_CLASS_AXIS;
        if (i >= 0)
                return i;
        *cls = RIG_CLASS_CAMERA;
        return rig_camera_index(rig, device);
}

/* Reads setting d of device i into s. */
static void read_setting(const struct rig *rig, const struct desc *d, int i, struct rig_setting *s)
{
        *s = (struct rig_setting){.name = d->name, .unit = d->unit, .min = RATE_MIN};
        d->read(rig, i, s);
}

json_t *rig_settings_json(const struct rig *rig, const char *device)
{
        enum rig_class cls;
        int i = find_device(rig, device, &cls);
        json_t *o;

        if (i < 0 || !(o = json_object()))
                return NULL;
        for (size_t k = 0; k < sizeof(settings) / sizeof(settings[0]); k++) {
                struct rig_setting s;
                if (settings[k].cls != cls)
                        continue;
                read_setting(rig, &settings[k], i, &s);
                json_object_set_new(o, s.name,
                                    isnan(s.max) ? json_pack("{sfsn}", "value", s.value, "max")
                                                 : json_pack("{sfsfsfssss}", "value", s.value,
                                                             "min", s.min, "max", s.max, "unit",
                                                             s.unit, "limit", s.limit));
        }
        return o;
}

/* The entry of setting name of device (class and index into *cls, *i), or NULL with msg. */
static const struct desc *lookup(const struct rig *rig, const char *device, const char *name,
                                 int *i, char *msg, size_t len)
{
        enum rig_class cls;

        if ((*i = find_device(rig, device, &cls)) < 0) {
                snprintf(msg, len, "no axis or camera named '%s'", device);
                return NULL;
        }
        for (size_t k = 0; k < sizeof(settings) / sizeof(settings[0]); k++)
                if (settings[k].cls == cls && strcmp(settings[k].name, name) == 0)
                        return &settings[k];
        snprintf(msg, len, "%s '%s' has no setting '%s' (%s)",
                 cls == RIG_CLASS_AXIS ? "axis" : "camera", device, name,
                 cls == RIG_CLASS_AXIS ? "speed, accel" : "exposure_us, gain");
        return NULL;
}

/* The entry d, index i and state s of setting name of device; -ENOENT or -EOPNOTSUPP with
 * msg. */
static int find_setting(const struct rig *rig, const char *device, const char *name,
                        const struct desc **d, int *i, struct rig_setting *s, char *msg, size_t len)
{
        if (!(*d = lookup(rig, device, name, i, msg, len)))
                return -ENOENT;
        read_setting(rig, *d, *i, s);
        if (isnan(s->max))
                return snprintf(msg, len, "camera '%s': its driver cannot set its %s", device,
                                name),
                       -EOPNOTSUPP;
        return 0;
}

int rig_setting_get(const struct rig *rig, const char *device, const char *name,
                    struct rig_setting *ret, char *msg, size_t len)
{
        const struct desc *d;
        int i;

        return find_setting(rig, device, name, &d, &i, ret, msg, len);
}

int rig_setting_set(struct rig *rig, const char *device, const char *name, double value,
                    rig_done_fn done, void *userdata, char *msg, size_t len)
{
        const struct desc *d;
        struct rig_setting s;
        int i, r = find_setting(rig, device, name, &d, &i, &s, msg, len);

        if (r < 0)
                return r;
        if (!(value >= s.min && value <= s.max))
                return snprintf(msg, len, "%s %g %s outside [%g, %g] (max from %s)", name, value,
                                s.unit, s.min, s.max, s.limit),
                       -ERANGE;
        msg[0] = '\0';
        return d->apply(rig, i, value, done, userdata);
}

struct cam_request rig_camera_request(const struct rig *rig, int i, const struct cam_request *req)
{
        struct cam_request out = *req;

        out.exposure_us = out.exposure_us ?: rig->cam_defaults[i].exposure_us;
        out.gain = out.gain > 0 ? out.gain : rig->cam_defaults[i].gain;
        return out;
}
