/* rigconf.c - loads and validates the rig file (docs/rig-file.md).
 *
 * The parse is strict: unknown keys (in every entry and backend map), missing required
 * keys, out-of-range values, unset ${VAR}s, duplicate names and roles, references to
 * undefined buses and profiles, a device without a backend map or with two, two devices on
 * one bus address and two buses on one port are errors that name the file, line and key.
 * Defaults are filled in here, so the rest of gonio reads plain values. Each backend map is
 * parsed by its backend (struct rig_backend), found in the caller's table by the map's
 * key. */
#include <errno.h>
#include <limits.h>
#include <libfyaml.h>
#include <math.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#include "log.h"
#include "rigconf.h"

/* Reads an optional section that must be a list; returns its length (0 if absent). */
static int section_len(struct yconf *yc, struct fy_node *root, const char *key, int max,
                       struct fy_node **seq)
{
        int n;

        *seq = yconf_get(root, key);
        if (!*seq)
                return 0;
        n = yconf_seq_len(yc, *seq, key);
        if (n > max)
                return yconf_error(yc, *seq, key, "at most %d entries are supported", max);
        return n;
}

static int read_name(struct yconf *yc, struct fy_node *m, char *out, size_t len)
{
        int r = yconf_str_req(yc, m, "name", out, len);

        if (r < 0)
                return r;
        if (strpbrk(out, " /\t,"))
                return yconf_error(yc, yconf_get(m, "name"), "name",
                                   "'%s': names may not contain spaces, '/' or ','", out);
        return 0;
}

_Static_assert(RIG_MAX_LASERS <= GN_POSE_MAX_LASERS, "a pose holds every laser of a rig");

int rigconf_laser(const struct rig_config *rc, const char *name)
{
        for (size_t i = 0; i < rc->n_lasers; i++)
                if (strcmp(rc->lasers[i].name, name) == 0)
                        return i;
        return -ENOENT;
}

uint32_t rigconf_all_lasers(const struct rig_config *rc)
{
        return (uint32_t)((UINT64_C(1) << rc->n_lasers) - 1);
}

int rigconf_axis_of_role(const struct rig_config *rc, enum gn_role role)
{
        for (size_t i = 0; i < rc->n_axes; i++)
                if (rc->axes[i].role == (int)role)
                        return i;
        return -ENOENT;
}

void rigconf_default_profile(struct rig_modbus_profile *p)
{
        *p = (struct rig_modbus_profile){
                .name = "gonio-default",
                .reg_status = 0x0000,
                .reg_fault = 0x0001,
                .reg_position = 0x0002,
                .reg_target = 0x0010,
                .reg_speed = 0x0012,
                .reg_accel = 0x0013,
                .reg_command = 0x0020,
                .cmd_move = 1,
                .cmd_home = 2,
                .cmd_stop = 3,
                .cmd_reset = 4,
                .scale = 1000.0,
                .word_swap = false,
        };
}

static int read_u16(struct yconf *yc, struct fy_node *m, const char *key, uint16_t *out)
{
        long v = *out;
        int r = yconf_int(yc, m, key, 0, 0xffff, &v);

        *out = (uint16_t)v;
        return r;
}

static int parse_profile(struct rig_config *rc, struct fy_node *m, struct rig_modbus_profile *p)
{
        struct yconf *yc = &rc->yc;
        static const char *const keys[] = {"name",     "status",    "fault",    "position",
                                           "target",   "speed",     "accel",    "command",
                                           "cmd_move", "cmd_home",  "cmd_stop", "cmd_reset",
                                           "scale",    "word_swap", NULL};
        struct {
                const char *key;
                uint16_t *field;
        } regs[] = {
                {"status", &p->reg_status},     {"fault", &p->reg_fault},
                {"position", &p->reg_position}, {"target", &p->reg_target},
                {"speed", &p->reg_speed},       {"accel", &p->reg_accel},
                {"command", &p->reg_command},   {"cmd_move", &p->cmd_move},
                {"cmd_home", &p->cmd_home},     {"cmd_stop", &p->cmd_stop},
                {"cmd_reset", &p->cmd_reset},
        };
        int r;

        rigconf_default_profile(p);
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = read_name(yc, m, p->name, sizeof(p->name))) < 0)
                return r;
        for (size_t i = 0; i < ELEMENTSOF(regs); i++)
                if ((r = read_u16(yc, m, regs[i].key, regs[i].field)) < 0)
                        return r;
        if ((r = yconf_double(yc, m, "scale", 1e-3, 1e9, &p->scale)) < 0 ||
            (r = yconf_bool(yc, m, "word_swap", &p->word_swap)) < 0)
                return r;
        return 0;
}

/* Reads an int-valued key into an int field with bounds. */
static int read_int(struct yconf *yc, struct fy_node *m, const char *key, long min, long max,
                    int *out)
{
        long v = *out;
        int r = yconf_int(yc, m, key, min, max, &v);

        *out = (int)v;
        return r;
}

/* Bus types by their rig-file name. */
static const char *const bus_types[] = {
        [RIG_BUS_MODBUS_RTU] = "modbus-rtu",
        [RIG_BUS_MODBUS_TCP] = "modbus-tcp",
        [RIG_BUS_SIM] = "sim",
        [RIG_BUS_SERIAL] = "serial",
        [RIG_BUS_LOCAL] = "local",
};

const char *rigconf_bus_type_name(enum rig_bus_type t)
{
        return (size_t)t < ELEMENTSOF(bus_types) ? bus_types[t] : "?";
}

static int read_bus_type(struct yconf *yc, struct fy_node *m, enum rig_bus_type *ret)
{
        char type[32] = "";
        int r = yconf_str_req(yc, m, "type", type, sizeof(type));

        if (r < 0)
                return r;
        for (size_t i = 0; i < ELEMENTSOF(bus_types); i++)
                if (strcmp(type, bus_types[i]) == 0)
                        return *ret = i, 0;
        return yconf_error(yc, yconf_get(m, "type"), "type",
                           "'%s' is not a bus type (modbus-rtu, modbus-tcp, sim, serial)", type);
}

static int parse_bus(struct rig_config *rc, struct fy_node *m, struct rig_bus_conf *b)
{
        static const char *const keys[] = {"name",      "type",       "port",    "host",
                                           "tcp_port",  "baud",       "parity",  "data_bits",
                                           "stop_bits", "timeout_ms", "retries", NULL};
        struct yconf *yc = &rc->yc;
        char parity[4] = "N";
        int r;

        *b = (struct rig_bus_conf){.baud = 115200,
                                   .parity = 'N',
                                   .data_bits = 8,
                                   .stop_bits = 1,
                                   .timeout_ms = 200,
                                   .retries = 2};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = read_name(yc, m, b->name, sizeof(b->name))) < 0 ||
            (r = read_bus_type(yc, m, &b->type)) < 0 ||
            (r = yconf_str(yc, m, "port", b->port, sizeof(b->port))) < 0 ||
            (r = yconf_str(yc, m, "host", b->host, sizeof(b->host))) < 0 ||
            (r = yconf_str(yc, m, "parity", parity, sizeof(parity))) < 0)
                return r;
        if (!strchr("NEO", parity[0]) || parity[1])
                return yconf_error(yc, yconf_get(m, "parity"), "parity", "must be N, E or O");
        b->parity = parity[0];
        if ((r = read_int(yc, m, "baud", 300, 4000000, &b->baud)) < 0 ||
            (r = read_int(yc, m, "tcp_port", 0, 65535, &b->tcp_port)) < 0 ||
            (r = read_int(yc, m, "data_bits", 5, 8, &b->data_bits)) < 0 ||
            (r = read_int(yc, m, "stop_bits", 1, 2, &b->stop_bits)) < 0 ||
            (r = read_int(yc, m, "timeout_ms", 1, 60000, &b->timeout_ms)) < 0 ||
            (r = read_int(yc, m, "retries", 0, 10, &b->retries)) < 0)
                return r;
        if (b->type == RIG_BUS_MODBUS_TCP && !b->host[0])
                strcpy(b->host, "127.0.0.1");
        if (b->type != RIG_BUS_MODBUS_TCP && b->type != RIG_BUS_LOCAL && !b->port[0])
                return yconf_error(yc, m, "port", "required key is missing");
        return 0;
}

/* The axis's role: the key 'role' ("turntable", "light_arm", "camera_arm" or "none"),
 * else the role named like the axis, else none. */
static int read_role(struct yconf *yc, struct fy_node *m, struct rig_axis_conf *a)
{
        char role[RIG_NAME_MAX] = "";
        int r = yconf_str(yc, m, "role", role, sizeof(role));

        if (r < 0)
                return r;
        if (!role[0]) {
                a->role = gn_role_from_name(a->name);
                a->role = a->role < 0 ? -1 : a->role;
                return 0;
        }
        if (strcmp(role, "none") == 0)
                return a->role = -1, 0;
        a->role = gn_role_from_name(role);
        if (a->role < 0)
                return yconf_error(yc, yconf_get(m, "role"), "role",
                                   "unknown role '%s' (turntable, light_arm, camera_arm or none)",
                                   role);
        return 0;
}

/* The backend of rc's table named key, or NULL. */
static const struct rig_backend *find_backend(const struct rig_config *rc, const char *key)
{
        for (const struct rig_backend *const *b = rc->backends; b && *b; b++)
                if (strcmp((*b)->name, key) == 0)
                        return *b;
        return NULL;
}

/* Device classes as messages name them. */
static const char *const class_names[] = {
        [RIG_CLASS_AXIS] = "axes",
        [RIG_CLASS_SWITCH] = "lamps and lasers",
        [RIG_CLASS_CAMERA] = "cameras",
};

/* The names of the backends of class cls, "a, b", into buf. */
static const char *backend_names(const struct rig_config *rc, enum rig_class cls, char *buf,
                                 size_t len)
{
        size_t o = 0;

        buf[0] = '\0';
        for (const struct rig_backend *const *b = rc->backends; b && *b; b++)
                if ((*b)->cls == cls && o < len)
                        o += snprintf(buf + o, len - o, "%s%s", o ? ", " : "", (*b)->name);
        return buf[0] ? buf : "none known";
}

/* A key of a device entry that is neither a class key nor a backend of its class. */
static int unknown_key(struct rig_config *rc, struct fy_node *k, const char *key,
                       enum rig_class cls)
{
        const struct rig_backend *b = find_backend(rc, key);
        char names[128];

        backend_names(rc, cls, names, sizeof(names));
        if (b)
                return yconf_error(&rc->yc, k, key, "'%s' is a backend for %s, not for %s (%s)",
                                   key, class_names[b->cls], class_names[cls], names);
        if (strcmp(key, "backend") == 0 || strcmp(key, "bus") == 0)
                return yconf_error(&rc->yc, k, key,
                                   "unknown key: the backend and its settings, bus included, go "
                                   "in one map named after the backend (%s: { bus: ... })",
                                   names);
        return yconf_error(&rc->yc, k, key, "unknown key");
}

/* Checks the keys of device entry m: each is a class key (keys) or names a backend of class
 * cls, and exactly one does; *be and *map get that backend and its map. */
static int device_keys(struct rig_config *rc, struct fy_node *m, enum rig_class cls,
                       const char *const *keys, const struct rig_backend **be, struct fy_node **map)
{
        struct fy_node_pair *pair;
        void *iter = NULL;
        char names[128];

        *be = NULL;
        while ((pair = fy_node_mapping_iterate(m, &iter))) {
                struct fy_node *k = fy_node_pair_key(pair);
                const char *key = fy_node_get_scalar0(k) ?: "?";
                const struct rig_backend *b = find_backend(rc, key);
                bool class_key = false;

                for (const char *const *a = keys; *a; a++)
                        class_key = class_key || strcmp(*a, key) == 0;
                if (class_key)
                        continue;
                if (!b || b->cls != cls)
                        return unknown_key(rc, k, key, cls);
                if (*be)
                        return yconf_error(&rc->yc, k, key,
                                           "a second backend map (after '%s'): a device has "
                                           "exactly one",
                                           (*be)->name);
                *be = b;
                *map = fy_node_pair_value(pair);
        }
        if (!*be)
                return yconf_error(&rc->yc, yconf_get(m, "name") ?: m,
                                   backend_names(rc, cls, names, sizeof(names)),
                                   "no backend map in this entry (one of: %s)", names);
        return 0;
}

/* Checks the keys of device entry m (class keys and its one backend map) and has the backend
 * parse its map into bc; the map's bus goes into bus (RIG_NAME_MAX bytes). */
static int parse_backend(struct rig_config *rc, struct fy_node *m, enum rig_class cls,
                         const char *const *keys, char *bus, struct rig_backend_conf *bc)
{
        struct yconf *yc = &rc->yc;
        const struct rig_backend *be;
        _cleanup_free_ void *conf = NULL;
        struct fy_node *map = NULL;
        int r;

        if ((r = device_keys(rc, m, cls, keys, &be, &map)) < 0)
                return r;
        if (fy_node_get_type(map) != FYNT_MAPPING)
                return yconf_error(yc, map, be->name,
                                   "expected the backend's settings as a mapping (%s: { bus: "
                                   "... })",
                                   be->name);
        snprintf(bc->name, sizeof(bc->name), "%s", be->name);
        if ((r = yconf_str_req(yc, map, "bus", bus, RIG_NAME_MAX)) < 0)
                return r;
        if (be->conf_size && !(conf = calloc(1, be->conf_size)))
                return -ENOMEM;
        bc->addr = (struct rig_addr){};
        if ((r = be->parse_conf(yc, map, rc, conf, &bc->addr)) < 0)
                return r;
        bc->conf = TAKE_PTR(conf);
        return 0;
}

/* A continuous axis's way round: "shortest" (default), "positive" or "negative" (a
 * cable or a hose that must not wind up the other way). */
static int read_direction(struct yconf *yc, struct fy_node *m, struct rig_axis_conf *a)
{
        char dir[16] = "shortest";
        int r = yconf_str(yc, m, "direction", dir, sizeof(dir));

        if (r < 0)
                return r;
        a->direction = strcmp(dir, "positive") == 0 ? 1 : strcmp(dir, "negative") == 0 ? -1 : 0;
        if (a->direction == 0 && strcmp(dir, "shortest") != 0)
                return yconf_error(yc, yconf_get(m, "direction"), "direction",
                                   "'%s': shortest, positive or negative", dir);
        if (yconf_get(m, "direction") && !a->continuous)
                return yconf_error(yc, yconf_get(m, "direction"), "direction",
                                   "only a continuous axis has a way round");
        return 0;
}

/* The motion semantics keys of an axis (docs/rig-file.md, "Motion"). */
static int read_motion(struct yconf *yc, struct fy_node *m, struct rig_axis_conf *a)
{
        int r;

        if ((r = yconf_double(yc, m, "backlash", -30, 30, &a->backlash_deg)) < 0 ||
            (r = yconf_double(yc, m, "deadband", 0, 10, &a->deadband_deg)) < 0 ||
            (r = read_int(yc, m, "move_retries", 0, 10, &a->move_retries)) < 0 ||
            (r = yconf_bool(yc, m, "absolute_encoder", &a->absolute_encoder)) < 0)
                return r;
        if ((r = read_direction(yc, m, a)) < 0)
                return r;
        if (a->move_retries > 0 && a->deadband_deg <= 0)
                return yconf_error(yc, yconf_get(m, "move_retries"), "move_retries",
                                   "retries need a deadband > 0 to aim for");
        return 0;
}

/* max_accel: at least accel; accel when absent. */
static int read_max_accel(struct yconf *yc, struct fy_node *m, struct rig_axis_conf *a)
{
        int r;

        a->max_accel = a->accel;
        if ((r = yconf_double(yc, m, "max_accel", 0.1, 6553.5, &a->max_accel)) < 0)
                return r;
        if (a->max_accel < a->accel)
                return yconf_error(yc, yconf_get(m, "max_accel"), "max_accel",
                                   "must be at least accel (%g)", a->accel);
        return 0;
}

static int parse_axis(struct rig_config *rc, struct fy_node *m, struct rig_axis_conf *a)
{
        static const char *const keys[] = {
                "name",      "continuous",       "limits",          "max_speed",
                "accel",     "settle_ms",        "move_timeout_ms", "role",
                "backlash",  "deadband",         "move_retries",    "absolute_encoder",
                "direction", "move_overhead_ms", "max_accel",       NULL};
        struct yconf *yc = &rc->yc;
        double lim[2] = {-180, 180};
        int r;

        *a = (struct rig_axis_conf){
                .max_speed = 30, .accel = 60, .settle_ms = 50, .move_overhead_ms = 35};
        if ((r = parse_backend(rc, m, RIG_CLASS_AXIS, keys, a->bus, &a->backend)) < 0 ||
            (r = read_name(yc, m, a->name, sizeof(a->name))) < 0 ||
            (r = yconf_bool(yc, m, "continuous", &a->continuous)) < 0 ||
            (r = yconf_doubles(yc, m, "limits", lim, 2, 2, NULL)) < 0 ||
            (r = yconf_double(yc, m, "max_speed", 0.1, 6553.5, &a->max_speed)) < 0 ||
            (r = yconf_double(yc, m, "accel", 0.1, 6553.5, &a->accel)) < 0 ||
            (r = read_max_accel(yc, m, a)) < 0 ||
            (r = read_int(yc, m, "settle_ms", 0, 60000, &a->settle_ms)) < 0 ||
            (r = read_int(yc, m, "move_timeout_ms", 0, 3600000, &a->move_timeout_ms)) < 0 ||
            (r = read_int(yc, m, "move_overhead_ms", 0, 10000, &a->move_overhead_ms)) < 0 ||
            (r = read_role(yc, m, a)) < 0 || (r = read_motion(yc, m, a)) < 0)
                return r;
        if (a->continuous && yconf_get(m, "limits"))
                return yconf_error(yc, yconf_get(m, "limits"), "limits",
                                   "a continuous axis has no soft limits");
        if (lim[0] >= lim[1] || lim[0] < -3600 || lim[1] > 3600)
                return yconf_error(yc, yconf_get(m, "limits"), "limits",
                                   "need min < max within [-3600, 3600] degrees");
        a->min_deg = a->continuous ? 0 : lim[0];
        a->max_deg = a->continuous ? 360 : lim[1];
        return 0;
}

static int parse_switch_common(struct rig_config *rc, struct fy_node *m, const char *const *keys,
                               struct rig_switch_conf *s)
{
        struct yconf *yc = &rc->yc;
        int r;

        if ((r = parse_backend(rc, m, RIG_CLASS_SWITCH, keys, s->bus, &s->backend)) < 0 ||
            (r = read_name(yc, m, s->name, sizeof(s->name))) < 0 ||
            (r = read_int(yc, m, "warmup_ms", 0, 60000, &s->warmup_ms)) < 0 ||
            (r = yconf_double(yc, m, "max_on_s", 0, 86400, &s->max_on_s)) < 0 ||
            (r = yconf_bool(yc, m, "off_on_disconnect", &s->off_on_disconnect)) < 0)
                return r;
        return 0;
}

static int parse_lamp(struct rig_config *rc, struct fy_node *m, struct rig_switch_conf *s)
{
        static const char *const keys[] = {
                "name",    "warmup_ms", "max_on_s", "off_on_disconnect", "elevation", "radius",
                "azimuth", "intensity", NULL};
        struct yconf *yc = &rc->yc;
        int r;

        *s = (struct rig_switch_conf){.kind = RIG_SWITCH_LAMP,
                                      .radius_mm = 450,
                                      .intensity = 1e5,
                                      .max_on_s = RIG_LAMP_MAX_ON_S};
        if ((r = parse_switch_common(rc, m, keys, s)) < 0 ||
            (r = yconf_double(yc, m, "elevation", -90, 90, &s->elevation_deg)) < 0 ||
            (r = yconf_double(yc, m, "radius", 1, 1e5, &s->radius_mm)) < 0 ||
            (r = yconf_double(yc, m, "azimuth", -360, 360, &s->azimuth_deg)) < 0 ||
            (r = yconf_double(yc, m, "intensity", 0, 1e12, &s->intensity)) < 0)
                return r;
        if (!yconf_get(m, "elevation"))
                return yconf_error(yc, m, "elevation", "required key is missing");
        return 0;
}

static int parse_laser(struct rig_config *rc, struct fy_node *m, struct rig_switch_conf *s)
{
        static const char *const keys[] = {"name",    "warmup_ms", "max_on_s", "off_on_disconnect",
                                           "azimuth", "origin",    "width",    "power",
                                           "channel", NULL};
        static const char *const channels[] = {"red", "green", "blue"};
        struct yconf *yc = &rc->yc;
        char channel[16] = "red";
        int r;

        *s = (struct rig_switch_conf){.kind = RIG_SWITCH_LASER,
                                      .laser_origin = {600, 0, 150},
                                      .laser_width_mm = 0.5,
                                      .laser_power = 1e3,
                                      .max_on_s = RIG_LASER_MAX_ON_S,
                                      .off_on_disconnect = true};
        if ((r = parse_switch_common(rc, m, keys, s)) < 0 ||
            (r = yconf_double(yc, m, "azimuth", -360, 360, &s->laser_azimuth_deg)) < 0 ||
            (r = yconf_doubles(yc, m, "origin", s->laser_origin, 3, 3, NULL)) < 0 ||
            (r = yconf_double(yc, m, "width", 1e-3, 100, &s->laser_width_mm)) < 0 ||
            (r = yconf_double(yc, m, "power", 0, 1e12, &s->laser_power)) < 0 ||
            (r = yconf_str(yc, m, "channel", channel, sizeof(channel))) < 0)
                return r;
        for (s->laser_channel = 0; s->laser_channel < 3; s->laser_channel++)
                if (strcmp(channel, channels[s->laser_channel]) == 0)
                        return 0;
        return yconf_error(yc, yconf_get(m, "channel"), "channel", "must be red, green or blue");
}

static int parse_camera_geometry(struct yconf *yc, struct fy_node *m, struct rig_camera_conf *c)
{
        int r;

        if ((r = yconf_double(yc, m, "elevation", -90, 90, &c->elevation_deg)) < 0 ||
            (r = yconf_double(yc, m, "distance", 1, 1e5, &c->distance_mm)) < 0 ||
            (r = yconf_double(yc, m, "azimuth", -360, 360, &c->azimuth_deg)) < 0 ||
            (r = yconf_doubles(yc, m, "target", c->target, 3, 3, NULL)) < 0 ||
            (r = read_int(yc, m, "width", 16, 16384, &c->width)) < 0 ||
            (r = read_int(yc, m, "height", 16, 16384, &c->height)) < 0 ||
            (r = yconf_double(yc, m, "fx", 1, 1e6, &c->fx)) < 0 ||
            (r = yconf_double(yc, m, "fy", 1, 1e6, &c->fy)) < 0 ||
            (r = yconf_double(yc, m, "cx", -1e5, 1e5, &c->cx)) < 0 ||
            (r = yconf_double(yc, m, "cy", -1e5, 1e5, &c->cy)) < 0 ||
            (r = yconf_doubles(yc, m, "distortion", c->dist, 0, 5, NULL)) < 0)
                return r;
        return 0;
}

/* max_exposure_us and max_gain: at least the defaults exposure_us and gain. */
static int read_camera_limits(struct yconf *yc, struct fy_node *m, struct rig_camera_conf *c)
{
        int r;

        if ((r = read_int(yc, m, "max_exposure_us", RIG_EXPOSURE_US_MIN, RIG_EXPOSURE_US_MAX,
                          &c->max_exposure_us)) < 0 ||
            (r = yconf_double(yc, m, "max_gain", RIG_GAIN_MIN, RIG_GAIN_MAX, &c->max_gain)) < 0)
                return r;
        if (c->max_exposure_us && c->max_exposure_us < c->exposure_us)
                return yconf_error(yc, yconf_get(m, "max_exposure_us"), "max_exposure_us",
                                   "must be at least exposure_us (%d)", c->exposure_us);
        if (c->max_gain > 0 && c->max_gain < c->gain)
                return yconf_error(yc, yconf_get(m, "max_gain"), "max_gain",
                                   "must be at least gain (%g)", c->gain);
        return 0;
}

static int parse_camera(struct rig_config *rc, struct fy_node *m, struct rig_camera_conf *c)
{
        static const char *const keys[] = {"name",
                                           "elevation",
                                           "distance",
                                           "azimuth",
                                           "target",
                                           "width",
                                           "height",
                                           "fx",
                                           "fy",
                                           "cx",
                                           "cy",
                                           "distortion",
                                           "exposure_us",
                                           "gain",
                                           "bits",
                                           "readout_ms",
                                           "occlusion_deg",
                                           "frame_rate",
                                           "max_exposure_us",
                                           "max_gain",
                                           NULL};
        struct yconf *yc = &rc->yc;
        int r;

        *c = (struct rig_camera_conf){.distance_mm = 600,
                                      .width = 720,
                                      .height = 480,
                                      .fx = 1000,
                                      .fy = 1000,
                                      .exposure_us = 10000,
                                      .gain = 1,
                                      .bits = 8,
                                      .readout_ms = 30,
                                      .frame_rate = 30,
                                      .occlusion_deg = 5};
        if ((r = parse_backend(rc, m, RIG_CLASS_CAMERA, keys, c->bus, &c->backend)) < 0 ||
            (r = read_name(yc, m, c->name, sizeof(c->name))) < 0 ||
            (r = parse_camera_geometry(yc, m, c)) < 0 ||
            (r = read_int(yc, m, "exposure_us", RIG_EXPOSURE_US_MIN, RIG_EXPOSURE_US_MAX,
                          &c->exposure_us)) < 0 ||
            (r = yconf_double(yc, m, "gain", RIG_GAIN_MIN, RIG_GAIN_MAX, &c->gain)) < 0 ||
            (r = read_camera_limits(yc, m, c)) < 0 ||
            (r = read_int(yc, m, "bits", 8, 16, &c->bits)) < 0 ||
            (r = read_int(yc, m, "readout_ms", 0, 10000, &c->readout_ms)) < 0 ||
            (r = yconf_double(yc, m, "frame_rate", 0.1, 1000, &c->frame_rate)) < 0 ||
            (r = yconf_double(yc, m, "occlusion_deg", 0, 90, &c->occlusion_deg)) < 0)
                return r;
        if (c->bits != 8 && c->bits != 16)
                return yconf_error(yc, yconf_get(m, "bits"), "bits", "must be 8 or 16");
        if (!yconf_get(m, "cx"))
                c->cx = (c->width - 1) / 2.0;
        if (!yconf_get(m, "cy"))
                c->cy = (c->height - 1) / 2.0;
        return 0;
}

typedef int (*parse_fn)(struct rig_config *rc, struct fy_node *m, void *item);

/* Parses list section key into an array of max items of size bytes each. */
static int parse_section(struct rig_config *rc, struct fy_node *root, const char *key, void *array,
                         size_t size, int max, size_t *count, parse_fn fn)
{
        struct yconf *yc = &rc->yc;
        struct fy_node *seq;
        int n = section_len(yc, root, key, max, &seq);

        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(seq, i);
                int r;

                if (fy_node_get_type(item) != FYNT_MAPPING)
                        return yconf_error(yc, item, key, "entry %d is not a mapping", i);
                r = fn(rc, item, (char *)array + i * size);
                if (r < 0)
                        return r;
        }
        if (n >= 0)
                *count = n;
        return n < 0 ? n : 0;
}

/* The lasers: the list `lasers`, or the one mapping `laser` (the shorthand of one-laser rigs),
 * not both. */
static int parse_lasers(struct rig_config *rc, struct fy_node *root)
{
        struct fy_node *one = yconf_get(root, "laser"), *list = yconf_get(root, "lasers");

        struct fy_node *later = one && list && yconf_line(one) > yconf_line(list) ? one : list;

        if (one && list)
                return yconf_error(&rc->yc, later, later == one ? "laser" : "lasers",
                                   "write either 'laser' (one mapping) or 'lasers' (a list), "
                                   "not both");
        if (list)
                return parse_section(rc, root, "lasers", rc->lasers, sizeof(rc->lasers[0]),
                                     RIG_MAX_LASERS, &rc->n_lasers, (parse_fn)parse_laser);
        if (!one)
                return 0;
        if (fy_node_get_type(one) != FYNT_MAPPING)
                return yconf_error(&rc->yc, one, "laser",
                                   "expected a mapping (several lasers: a list 'lasers')");
        rc->n_lasers = 1;
        return parse_laser(rc, one, &rc->lasers[0]);
}

/* The mapping of entry index of section; for lasers written as the one mapping `laser`,
 * that mapping. */
static struct fy_node *entry_node(struct yconf *yc, const char *section, int index)
{
        struct fy_node *n = yconf_get(yconf_root(yc), section);

        if (!n && strcmp(section, "lasers") == 0)
                n = yconf_get(yconf_root(yc), "laser");

        return n && fy_node_get_type(n) == FYNT_SEQUENCE ? yconf_seq_item(n, index) : n;
}

/* Where an error about key of an entry points: the key's value, else the entry's name,
 * else the entry. */
static struct fy_node *entry_key(struct yconf *yc, const char *section, int index, const char *key)
{
        struct fy_node *m = entry_node(yc, section, index);

        return yconf_get(m, key) ?: yconf_get(m, "name") ?: m;
}

/* Where an error about key of the backend map of an entry points: the key's value, else
 * the map, else the entry's name. */
static struct fy_node *backend_key(struct yconf *yc, const char *section, int index,
                                   const char *backend, const char *key)
{
        struct fy_node *map = yconf_get(entry_node(yc, section, index), backend);

        return yconf_get(map, key) ?: map ?: entry_key(yc, section, index, "name");
}

/* A named entry of the rig file, and its backend when it is a device. */
struct ref {
        const char *section; /* rig-file section: "axes", "lamps", ... */
        const char *kind;    /* for messages: "axis", "lamp", ... */
        int index;           /* entry in section */
        const char *name;
        const char *bus;                   /* NULL: not a device */
        const struct rig_backend_conf *be; /* NULL: not a device */
};

/* The ref of a switch (lamp or laser). */
static struct ref switch_ref(const char *section, size_t index, const struct rig_switch_conf *s)
{
        return (struct ref){.section = section,
                            .kind = s->kind == RIG_SWITCH_LASER ? "laser" : "lamp",
                            .index = index,
                            .name = s->name,
                            .bus = s->bus,
                            .be = &s->backend};
}

/* Lists the devices of rc (axes, lamps, laser, cameras) into refs; returns their number. */
static size_t device_refs(const struct rig_config *rc, struct ref *refs)
{
        size_t n = 0;

        for (size_t i = 0; i < rc->n_axes; i++) {
                const struct rig_axis_conf *a = &rc->axes[i];

                refs[n++] = (struct ref){"axes", "axis", i, a->name, a->bus, &a->backend};
        }
        for (size_t i = 0; i < rc->n_lamps; i++)
                refs[n++] = switch_ref("lamps", i, &rc->lamps[i]);
        for (size_t i = 0; i < rc->n_lasers; i++)
                refs[n++] = switch_ref("lasers", i, &rc->lasers[i]);
        for (size_t i = 0; i < rc->n_cameras; i++) {
                const struct rig_camera_conf *c = &rc->cameras[i];

                refs[n++] = (struct ref){"cameras", "camera", i, c->name, c->bus, &c->backend};
        }
        return n;
}

/* Names are unique within refs; the error points at the name written last in the file. */
static int check_names(struct yconf *yc, const struct ref *refs, size_t n, const char *what)
{
        for (size_t j = 0; j < n; j++)
                for (size_t i = 0; i < j; i++) {
                        struct fy_node *a = entry_key(yc, refs[i].section, refs[i].index, "name");
                        struct fy_node *b = entry_key(yc, refs[j].section, refs[j].index, "name");

                        if (strcmp(refs[i].name, refs[j].name) != 0)
                                continue;
                        if (yconf_line(a) > yconf_line(b)) {
                                struct fy_node *t = a;
                                a = b, b = t;
                        }
                        return yconf_error(yc, b, "name",
                                           "%s name '%s' is used twice (first at line %d)", what,
                                           refs[j].name, yconf_line(a));
                }
        return 0;
}

/* Whether devices a and b are at one place of one bus (struct rig_addr). */
static bool same_place(const struct ref *a, const struct ref *b)
{
        const struct rig_addr *x = &a->be->addr, *y = &b->be->addr;

        if (!x->key || !y->key || strcmp(a->bus, b->bus) != 0 || strcmp(x->key, y->key) != 0 ||
            x->value != y->value)
                return false;
        return !x->sub_key || !y->sub_key || x->sub == y->sub;
}

/* One address is one device: a drive takes a Modbus unit, a relay module's coil one lamp.
 * Two devices at one place would drive one motor or one lamp twice. The error points at
 * the address key in the backend map of the device written last. */
static int check_addresses(struct yconf *yc, const struct ref *d, size_t n)
{
        for (size_t j = 0; j < n; j++)
                for (size_t i = 0; i < j; i++) {
                        const struct rig_addr *a = &d[j].be->addr;

                        if (!same_place(&d[i], &d[j]))
                                continue;
                        if (a->sub_key && d[i].be->addr.sub_key)
                                return yconf_error(
                                        yc,
                                        backend_key(yc, d[j].section, d[j].index, d[j].be->name,
                                                    a->sub_key),
                                        a->sub_key,
                                        "%s '%s' and %s '%s' are both on %s %d of %s %d on bus "
                                        "'%s'",
                                        d[i].kind, d[i].name, d[j].kind, d[j].name, a->sub_key,
                                        a->sub, a->key, a->value, d[j].bus);
                        return yconf_error(
                                yc,
                                backend_key(yc, d[j].section, d[j].index, d[j].be->name, a->key),
                                a->key,
                                "%s '%s' and %s '%s' are both on %s %d on bus '%s' (one device "
                                "per %s)",
                                d[i].kind, d[i].name, d[j].kind, d[j].name, a->key, a->value,
                                d[j].bus, a->key);
                }
        return 0;
}

/* Two buses on one serial port, socket or TCP peer would be two masters on one line. */
static int check_ports(struct yconf *yc, const struct rig_config *rc)
{
        for (size_t j = 0; j < rc->n_buses; j++)
                for (size_t i = 0; i < j; i++) {
                        const struct rig_bus_conf *a = &rc->buses[i], *b = &rc->buses[j];
                        bool tcp = b->type == RIG_BUS_MODBUS_TCP;

                        if ((a->type == RIG_BUS_MODBUS_TCP) != tcp || b->type == RIG_BUS_LOCAL)
                                continue; /* local buses have no port */
                        if (tcp && strcmp(a->host, b->host) == 0 && a->tcp_port == b->tcp_port)
                                return yconf_error(yc, entry_key(yc, "buses", j, "tcp_port"),
                                                   "tcp_port", "buses '%s' and '%s' both use %s:%d",
                                                   a->name, b->name, b->host, b->tcp_port);
                        if (!tcp && a->port[0] && strcmp(a->port, b->port) == 0) /* local: none */
                                return yconf_error(yc, entry_key(yc, "buses", j, "port"), "port",
                                                   "buses '%s' and '%s' both use port '%s'",
                                                   a->name, b->name, b->port);
                }
        return 0;
}

/* At most one axis per role; the error points at the second axis's role (or name). */
static int check_roles(struct yconf *yc, const struct rig_config *rc)
{
        for (size_t j = 0; j < rc->n_axes; j++)
                for (size_t i = 0; i < j; i++)
                        if (rc->axes[i].role >= 0 && rc->axes[i].role == rc->axes[j].role)
                                return yconf_error(yc, entry_key(yc, "axes", j, "role"), "role",
                                                   "axes '%s' and '%s' both have role '%s'",
                                                   rc->axes[i].name, rc->axes[j].name,
                                                   gn_role_name(rc->axes[j].role));
        return 0;
}

/* Names of devices, buses and profiles; Modbus addresses; bus ports; axis roles. */
static int check_unique(struct yconf *yc, const struct rig_config *rc)
{
        struct ref refs[RIG_MAX_BUSES + RIG_MAX_AXES + RIG_MAX_LAMPS + RIG_MAX_LASERS +
                        RIG_MAX_CAMERAS];
        size_t n = device_refs(rc, refs);
        int r;

        if ((r = check_names(yc, refs, n, "device")) < 0 || (r = check_addresses(yc, refs, n)) < 0)
                return r;
        n = 0;
        for (size_t i = 0; i < rc->n_buses; i++)
                refs[n++] = (struct ref){"buses", "bus", i, rc->buses[i].name};
        if ((r = check_names(yc, refs, n, "bus")) < 0)
                return r;
        n = 0;
        for (size_t i = 1; i < rc->n_profiles; i++) /* [0] is the built-in default */
                refs[n++] = (struct ref){"profiles", "profile", i - 1, rc->profiles[i].name};
        for (size_t i = 0; i < n; i++)
                if (strcmp(refs[i].name, rc->profiles[0].name) == 0)
                        return yconf_error(yc, entry_key(yc, "profiles", i, "name"), "name",
                                           "profile '%s' is built in; choose another name",
                                           refs[i].name);
        if ((r = check_names(yc, refs, n, "profile")) < 0 || (r = check_ports(yc, rc)) < 0)
                return r;
        return check_roles(yc, rc);
}

/* The bus of device ref must exist and be of a kind its backend runs on. */
static int check_bus(struct yconf *yc, const struct rig_config *rc, const struct ref *d)
{
        struct fy_node *node = backend_key(yc, d->section, d->index, d->be->name, "bus");
        const struct rig_backend *be = find_backend(rc, d->be->name);
        const struct rig_bus_conf *b = rigconf_bus(rc, d->bus);

        if (!b)
                return yconf_error(yc, node, "bus", "%s '%s': no bus named '%s'", d->section,
                                   d->name, d->bus);
        if (!(be->bus_types & (1u << b->type)))
                return yconf_error(yc, node, "bus",
                                   "%s '%s': bus '%s' is of the wrong type (%s; backend '%s' "
                                   "does not run on it)",
                                   d->section, d->name, d->bus, bus_types[b->type], be->name);
        return 0;
}

static int check_references(struct yconf *yc, const struct rig_config *rc)
{
        struct ref refs[RIG_MAX_AXES + RIG_MAX_LAMPS + RIG_MAX_LASERS + RIG_MAX_CAMERAS];
        size_t n = device_refs(rc, refs);
        int r = 0;

        for (size_t i = 0; r >= 0 && i < n; i++)
                r = check_bus(yc, rc, &refs[i]);
        return r;
}

/* The directory of the rig file, absolute, into real. */
static int rig_dir(const struct rig_config *rc, char real[PATH_MAX])
{
        char dir[RIG_PATH_MAX];
        char *slash;

        snprintf(dir, sizeof(dir), "%s", rc->path);
        slash = strrchr(dir, '/');
        if (!slash)
                snprintf(dir, sizeof(dir), ".");
        else
                slash[slash == dir] = '\0'; /* "/rig.yaml": "/" */
        return realpath(dir, real) ? 0 : -errno;
}

/* The key `calibration`: a path relative to the rig file's directory, made absolute. */
static int read_calibration(struct rig_config *rc, struct fy_node *root)
{
        struct fy_node *node = yconf_get(root, "calibration");
        char rel[RIG_PATH_MAX] = "", dir[PATH_MAX] = "";
        int r = yconf_str(&rc->yc, root, "calibration", rel, sizeof(rel));

        if (r <= 0)
                return r;
        if (!rel[0])
                return yconf_error(&rc->yc, node, "calibration", "empty path");
        if (rel[0] != '/' && (r = rig_dir(rc, dir)) < 0)
                return yconf_error(&rc->yc, node, "calibration",
                                   "cannot resolve the rig file's directory: %s", strerror(-r));
        if ((size_t)snprintf(rc->calibration, sizeof(rc->calibration), "%s%s%s", dir,
                             dir[0] ? "/" : "", rel) >= sizeof(rc->calibration))
                return yconf_error(&rc->yc, node, "calibration", "path too long");
        return 0;
}

static int parse_root(struct rig_config *rc)
{
        struct yconf *yc = &rc->yc;
        static const char *const keys[] = {"rig",   "profiles",    "buses",  "axes",
                                           "lamps", "laser",       "lasers", "cameras",
                                           "scene", "calibration", NULL};
        struct fy_node *root = yconf_root(yc);
        int r;

        if (!root)
                return yconf_error(yc, NULL, NULL, "the rig file is empty");
        if ((r = yconf_check_keys(yc, root, keys)) < 0 ||
            (r = yconf_str_req(yc, root, "rig", rc->name, sizeof(rc->name))) < 0)
                return r;
        rigconf_default_profile(&rc->profiles[0]);
        if ((r = parse_section(rc, root, "profiles", rc->profiles + 1, sizeof(rc->profiles[0]),
                               ELEMENTSOF(rc->profiles) - 1, &rc->n_profiles,
                               (parse_fn)parse_profile)) < 0)
                return r;
        rc->n_profiles += 1; /* the built-in default comes first */
        if ((r = parse_section(rc, root, "buses", rc->buses, sizeof(rc->buses[0]), RIG_MAX_BUSES,
                               &rc->n_buses, (parse_fn)parse_bus)) < 0 ||
            (r = parse_section(rc, root, "axes", rc->axes, sizeof(rc->axes[0]), RIG_MAX_AXES,
                               &rc->n_axes, (parse_fn)parse_axis)) < 0 ||
            (r = parse_section(rc, root, "lamps", rc->lamps, sizeof(rc->lamps[0]), RIG_MAX_LAMPS,
                               &rc->n_lamps, (parse_fn)parse_lamp)) < 0 ||
            (r = parse_lasers(rc, root)) < 0 ||
            (r = parse_section(rc, root, "cameras", rc->cameras, sizeof(rc->cameras[0]),
                               RIG_MAX_CAMERAS, &rc->n_cameras, (parse_fn)parse_camera)) < 0)
                return r;
        if ((r = read_calibration(rc, root)) < 0 || (r = check_unique(yc, rc)) < 0)
                return r;
        return check_references(yc, rc);
}

static int read_text(const char *path, char **ret)
{
        _cleanup_fclose_ FILE *f = fopen(path, "re");
        _cleanup_free_ char *buf = NULL;
        size_t len = 0;

        if (!f)
                return -errno;
        if (getdelim(&buf, &len, '\0', f) < 0) {
                if (!feof(f))
                        return -errno;
                if (buf) /* an empty file: getdelim allocated but wrote nothing */
                        buf[0] = '\0';
        }
        if (!buf && !(buf = strdup("")))
                return -ENOMEM;
        *ret = TAKE_PTR(buf);
        return 0;
}

static int load(const char *path, const struct rig_backend *const *backends, bool stored,
                struct rig_config **ret, char *err, size_t errlen)
{
        struct rig_config *rc = calloc(1, sizeof(*rc));
        int r;

        if (!rc)
                return -ENOMEM;
        snprintf(rc->path, sizeof(rc->path), "%s", path);
        rc->backends = backends;
        r = read_text(path, &rc->text);
        if (r < 0) {
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                rigconf_free(rc);
                return r;
        }
        r = yconf_open_string(&rc->yc, rc->path, rc->text, err, errlen);
        rc->yc.keep_unset_vars = stored;
        if (r >= 0)
                r = parse_root(rc);
        if (r < 0) {
                rigconf_free(rc);
                return r;
        }
        *ret = rc;
        return 0;
}

int rigconf_load(const char *path, const struct rig_backend *const *backends,
                 struct rig_config **ret, char *err, size_t errlen)
{
        return load(path, backends, false, ret, err, errlen);
}

int rigconf_load_stored(const char *path, const struct rig_backend *const *backends,
                        struct rig_config **ret, char *err, size_t errlen)
{
        return load(path, backends, true, ret, err, errlen);
}

struct rig_config *rigconf_free(struct rig_config *rc)
{
        if (!rc)
                return NULL;
        /* every slot, parsed or not: a failed load leaves the confs parsed so far */
        for (size_t i = 0; i < RIG_MAX_AXES; i++)
                free((void *)rc->axes[i].backend.conf);
        for (size_t i = 0; i < RIG_MAX_LAMPS; i++)
                free((void *)rc->lamps[i].backend.conf);
        for (size_t i = 0; i < RIG_MAX_LASERS; i++)
                free((void *)rc->lasers[i].backend.conf);
        for (size_t i = 0; i < RIG_MAX_CAMERAS; i++)
                free((void *)rc->cameras[i].backend.conf);
        yconf_close(&rc->yc);
        free(rc->text);
        free(rc);
        return NULL;
}

struct fy_node *rigconf_scene(struct rig_config *rc)
{
        return yconf_get(yconf_root(&rc->yc), "scene");
}

const struct rig_bus_conf *rigconf_bus(const struct rig_config *rc, const char *name)
{
        for (size_t i = 0; i < rc->n_buses; i++)
                if (strcmp(rc->buses[i].name, name) == 0)
                        return &rc->buses[i];
        return NULL;
}

const struct rig_modbus_profile *rigconf_profile(const struct rig_config *rc, const char *name)
{
        for (size_t i = 0; i < rc->n_profiles; i++)
                if (strcmp(rc->profiles[i].name, name) == 0)
                        return &rc->profiles[i];
        return NULL;
}
