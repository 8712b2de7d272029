/* rigconf.c - loads and validates the rig file (docs/rig-file.md).
 *
 * The parse is strict: unknown keys (in every entry), missing required keys,
 * out-of-range values, unset ${VAR}s, duplicate names and roles, references to
 * undefined buses, two devices on one Modbus address and two buses on one port are
 * errors that name the file, line and key. Defaults are filled in here, so the rest
 * of gonio reads plain values. */
#include <errno.h>
#include <libfyaml.h>
#include <math.h>
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

static int parse_profile(struct yconf *yc, struct fy_node *m, struct rig_modbus_profile *p)
{
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

static int parse_bus(struct yconf *yc, struct fy_node *m, struct rig_bus_conf *b)
{
        static const char *const keys[] = {"name",      "type",       "port",    "host",
                                           "tcp_port",  "baud",       "parity",  "data_bits",
                                           "stop_bits", "timeout_ms", "retries", NULL};
        char type[32] = "", parity[4] = "N";
        int r;

        *b = (struct rig_bus_conf){.baud = 115200,
                                   .parity = 'N',
                                   .data_bits = 8,
                                   .stop_bits = 1,
                                   .timeout_ms = 200,
                                   .retries = 2};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = read_name(yc, m, b->name, sizeof(b->name))) < 0 ||
            (r = yconf_str_req(yc, m, "type", type, sizeof(type))) < 0 ||
            (r = yconf_str(yc, m, "port", b->port, sizeof(b->port))) < 0 ||
            (r = yconf_str(yc, m, "host", b->host, sizeof(b->host))) < 0 ||
            (r = yconf_str(yc, m, "parity", parity, sizeof(parity))) < 0)
                return r;
        if (strcmp(type, "modbus-rtu") == 0)
                b->type = RIG_BUS_MODBUS_RTU;
        else if (strcmp(type, "modbus-tcp") == 0)
                b->type = RIG_BUS_MODBUS_TCP;
        else if (strcmp(type, "sim") == 0)
                b->type = RIG_BUS_SIM;
        else if (strcmp(type, "serial") == 0)
                b->type = RIG_BUS_SERIAL;
        else
                return yconf_error(yc, yconf_get(m, "type"), "type",
                                   "'%s' is not a bus type (modbus-rtu, modbus-tcp, sim, serial)",
                                   type);
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
        if (b->type != RIG_BUS_MODBUS_TCP && !b->port[0])
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

static int parse_axis(struct yconf *yc, struct fy_node *m, struct rig_axis_conf *a)
{
        static const char *const keys[] = {
                "name",   "backend",   "bus",   "unit",      "profile",         "continuous",
                "limits", "max_speed", "accel", "settle_ms", "move_timeout_ms", "role",
                NULL};
        double lim[2] = {-180, 180};
        int r;

        *a = (struct rig_axis_conf){.unit = 1,
                                    .profile = "gonio-default",
                                    .max_speed = 30,
                                    .accel = 60,
                                    .settle_ms = 50};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = read_name(yc, m, a->name, sizeof(a->name))) < 0 ||
            (r = yconf_str_req(yc, m, "backend", a->backend, sizeof(a->backend))) < 0 ||
            (r = yconf_str_req(yc, m, "bus", a->bus, sizeof(a->bus))) < 0 ||
            (r = yconf_str(yc, m, "profile", a->profile, sizeof(a->profile))) < 0 ||
            (r = read_int(yc, m, "unit", 1, 247, &a->unit)) < 0 ||
            (r = yconf_bool(yc, m, "continuous", &a->continuous)) < 0 ||
            (r = yconf_doubles(yc, m, "limits", lim, 2, 2, NULL)) < 0 ||
            (r = yconf_double(yc, m, "max_speed", 0.1, 6553.5, &a->max_speed)) < 0 ||
            (r = yconf_double(yc, m, "accel", 0.1, 6553.5, &a->accel)) < 0 ||
            (r = read_int(yc, m, "settle_ms", 0, 60000, &a->settle_ms)) < 0 ||
            (r = read_int(yc, m, "move_timeout_ms", 0, 3600000, &a->move_timeout_ms)) < 0 ||
            (r = read_role(yc, m, a)) < 0)
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

static int parse_switch_common(struct yconf *yc, struct fy_node *m, struct rig_switch_conf *s)
{
        int r;

        if ((r = read_name(yc, m, s->name, sizeof(s->name))) < 0 ||
            (r = yconf_str_req(yc, m, "backend", s->backend, sizeof(s->backend))) < 0 ||
            (r = yconf_str_req(yc, m, "bus", s->bus, sizeof(s->bus))) < 0 ||
            (r = read_int(yc, m, "unit", 1, 247, &s->unit)) < 0 ||
            (r = read_int(yc, m, "coil", 0, 65535, &s->coil)) < 0 ||
            (r = read_int(yc, m, "warmup_ms", 0, 60000, &s->warmup_ms)) < 0)
                return r;
        return 0;
}

static int parse_lamp(struct yconf *yc, struct fy_node *m, struct rig_switch_conf *s)
{
        static const char *const keys[] = {"name",    "backend",   "bus",       "unit",
                                           "coil",    "warmup_ms", "elevation", "radius",
                                           "azimuth", "intensity", NULL};
        int r;

        *s = (struct rig_switch_conf){
                .kind = RIG_SWITCH_LAMP, .unit = 1, .radius_mm = 450, .intensity = 1e5};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 || (r = parse_switch_common(yc, m, s)) < 0 ||
            (r = yconf_double(yc, m, "elevation", -90, 90, &s->elevation_deg)) < 0 ||
            (r = yconf_double(yc, m, "radius", 1, 1e5, &s->radius_mm)) < 0 ||
            (r = yconf_double(yc, m, "azimuth", -360, 360, &s->azimuth_deg)) < 0 ||
            (r = yconf_double(yc, m, "intensity", 0, 1e12, &s->intensity)) < 0)
                return r;
        if (!yconf_get(m, "elevation"))
                return yconf_error(yc, m, "elevation", "required key is missing");
        return 0;
}

static int parse_laser(struct yconf *yc, struct fy_node *m, struct rig_switch_conf *s)
{
        static const char *const keys[] = {"name",  "backend",   "bus",     "unit",
                                           "coil",  "warmup_ms", "azimuth", "origin",
                                           "width", "power",     "channel", NULL};
        static const char *const channels[] = {"red", "green", "blue"};
        char channel[16] = "red";
        int r;

        *s = (struct rig_switch_conf){.kind = RIG_SWITCH_LASER,
                                      .unit = 1,
                                      .laser_origin = {600, 0, 150},
                                      .laser_width_mm = 0.5,
                                      .laser_power = 1e3};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 || (r = parse_switch_common(yc, m, s)) < 0 ||
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

static int parse_camera(struct yconf *yc, struct fy_node *m, struct rig_camera_conf *c)
{
        static const char *const keys[] = {
                "name",   "backend",    "bus",         "elevation", "distance", "azimuth",
                "target", "width",      "height",      "fx",        "fy",       "cx",
                "cy",     "distortion", "exposure_us", "gain",      "bits",     NULL};
        int r;

        *c = (struct rig_camera_conf){.distance_mm = 600,
                                      .width = 720,
                                      .height = 480,
                                      .fx = 1000,
                                      .fy = 1000,
                                      .exposure_us = 10000,
                                      .gain = 1,
                                      .bits = 8};
        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = read_name(yc, m, c->name, sizeof(c->name))) < 0 ||
            (r = yconf_str_req(yc, m, "backend", c->backend, sizeof(c->backend))) < 0 ||
            (r = yconf_str_req(yc, m, "bus", c->bus, sizeof(c->bus))) < 0 ||
            (r = parse_camera_geometry(yc, m, c)) < 0 ||
            (r = read_int(yc, m, "exposure_us", RIG_EXPOSURE_US_MIN, RIG_EXPOSURE_US_MAX,
                          &c->exposure_us)) < 0 ||
            (r = yconf_double(yc, m, "gain", RIG_GAIN_MIN, RIG_GAIN_MAX, &c->gain)) < 0 ||
            (r = read_int(yc, m, "bits", 8, 16, &c->bits)) < 0)
                return r;
        if (c->bits != 8 && c->bits != 16)
                return yconf_error(yc, yconf_get(m, "bits"), "bits", "must be 8 or 16");
        if (!yconf_get(m, "cx"))
                c->cx = (c->width - 1) / 2.0;
        if (!yconf_get(m, "cy"))
                c->cy = (c->height - 1) / 2.0;
        return 0;
}

typedef int (*parse_fn)(struct yconf *yc, struct fy_node *m, void *item);

/* Parses list section key into an array of max items of size bytes each. */
static int parse_section(struct yconf *yc, struct fy_node *root, const char *key, void *array,
                         size_t size, int max, size_t *count, parse_fn fn)
{
        struct fy_node *seq;
        int n = section_len(yc, root, key, max, &seq);

        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(seq, i);
                int r;

                if (fy_node_get_type(item) != FYNT_MAPPING)
                        return yconf_error(yc, item, key, "entry %d is not a mapping", i);
                r = fn(yc, item, (char *)array + i * size);
                if (r < 0)
                        return r;
        }
        if (n >= 0)
                *count = n;
        return n < 0 ? n : 0;
}

/* The mapping of entry index of section; for the laser, the mapping itself. */
static struct fy_node *entry_node(struct yconf *yc, const char *section, int index)
{
        struct fy_node *n = yconf_get(yconf_root(yc), section);

        return n && fy_node_get_type(n) == FYNT_SEQUENCE ? yconf_seq_item(n, index) : n;
}

/* Where an error about key of an entry points: the key's value, else the entry's name,
 * else the entry. */
static struct fy_node *entry_key(struct yconf *yc, const char *section, int index, const char *key)
{
        struct fy_node *m = entry_node(yc, section, index);

        return yconf_get(m, key) ?: yconf_get(m, "name") ?: m;
}

/* A named entry of the rig file, and its Modbus address when it has one. */
struct ref {
        const char *section; /* rig-file section: "axes", "lamps", ... */
        const char *kind;    /* for messages: "axis", "lamp", ... */
        int index;           /* entry in section */
        const char *name;
        const char *bus; /* NULL: no Modbus address */
        int unit, coil;  /* coil -1: a drive (the whole unit) */
};

/* The ref of a switch (lamp or laser). */
static struct ref switch_ref(const char *section, size_t index, const struct rig_switch_conf *s)
{
        return (struct ref){.section = section,
                            .kind = s->kind == RIG_SWITCH_LASER ? "laser" : "lamp",
                            .index = index,
                            .name = s->name,
                            .bus = s->bus,
                            .unit = s->unit,
                            .coil = s->coil};
}

/* Lists the devices of rc (axes, lamps, laser, cameras) into refs; returns their number. */
static size_t device_refs(const struct rig_config *rc, struct ref *refs)
{
        size_t n = 0;

        for (size_t i = 0; i < rc->n_axes; i++) {
                const struct rig_axis_conf *a = &rc->axes[i];

                refs[n++] = (struct ref){"axes", "axis", i, a->name, a->bus, a->unit, -1};
        }
        for (size_t i = 0; i < rc->n_lamps; i++)
                refs[n++] = switch_ref("lamps", i, &rc->lamps[i]);
        if (rc->has_laser)
                refs[n++] = switch_ref("laser", 0, &rc->laser);
        for (size_t i = 0; i < rc->n_cameras; i++)
                refs[n++] = (struct ref){"cameras", "camera", i, rc->cameras[i].name};
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

/* One Modbus unit is one device: a drive (one axis) or a relay module (one switch per
 * coil). Two devices on one address would drive one motor or one lamp twice. */
static int check_addresses(struct yconf *yc, const struct ref *d, size_t n)
{
        for (size_t j = 0; j < n; j++)
                for (size_t i = 0; i < j; i++) {
                        bool switches = d[i].coil >= 0 && d[j].coil >= 0;

                        if (!d[i].bus || !d[j].bus || strcmp(d[i].bus, d[j].bus) != 0 ||
                            d[i].unit != d[j].unit || (switches && d[i].coil != d[j].coil))
                                continue;
                        if (switches)
                                return yconf_error(
                                        yc, entry_key(yc, d[j].section, d[j].index, "coil"), "coil",
                                        "%s '%s' and %s '%s' are both on coil %d of "
                                        "unit %d on bus '%s'",
                                        d[i].kind, d[i].name, d[j].kind, d[j].name, d[j].coil,
                                        d[j].unit, d[j].bus);
                        return yconf_error(
                                yc, entry_key(yc, d[j].section, d[j].index, "unit"), "unit",
                                "%s '%s' and %s '%s' are both on unit %d on bus '%s' "
                                "(a unit is one drive or one relay module)",
                                d[i].kind, d[i].name, d[j].kind, d[j].name, d[j].unit, d[j].bus);
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

                        if ((a->type == RIG_BUS_MODBUS_TCP) != tcp)
                                continue;
                        if (tcp && strcmp(a->host, b->host) == 0 && a->tcp_port == b->tcp_port)
                                return yconf_error(yc, entry_key(yc, "buses", j, "tcp_port"),
                                                   "tcp_port", "buses '%s' and '%s' both use %s:%d",
                                                   a->name, b->name, b->host, b->tcp_port);
                        if (!tcp && strcmp(a->port, b->port) == 0)
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
        struct ref refs[RIG_MAX_BUSES + RIG_MAX_AXES + RIG_MAX_LAMPS + 1 + RIG_MAX_CAMERAS];
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

/* The device's bus must exist and be of a fitting kind (sim bus only for cameras). */
static int check_bus(struct yconf *yc, struct rig_config *rc, const char *section, int index,
                     const char *dev, const char *bus, bool camera)
{
        struct fy_node *node = entry_key(yc, section, index, "bus");
        const struct rig_bus_conf *b = rigconf_bus(rc, bus);

        if (!b)
                return yconf_error(yc, node, "bus", "%s '%s': no bus named '%s'", section, dev,
                                   bus);
        if ((b->type == RIG_BUS_SIM) != camera)
                return yconf_error(yc, node, "bus", "%s '%s': bus '%s' is of the wrong type",
                                   section, dev, bus);
        return 0;
}

static int check_references(struct yconf *yc, struct rig_config *rc)
{
        int r = 0;

        for (size_t i = 0; r >= 0 && i < rc->n_axes; i++) {
                r = check_bus(yc, rc, "axes", i, rc->axes[i].name, rc->axes[i].bus, false);
                if (r >= 0 && !rigconf_profile(rc, rc->axes[i].profile))
                        r = yconf_error(yc, entry_key(yc, "axes", i, "profile"), "profile",
                                        "no register profile named '%s'", rc->axes[i].profile);
        }
        for (size_t i = 0; r >= 0 && i < rc->n_lamps; i++)
                r = check_bus(yc, rc, "lamps", i, rc->lamps[i].name, rc->lamps[i].bus, false);
        if (r >= 0 && rc->has_laser)
                r = check_bus(yc, rc, "laser", 0, rc->laser.name, rc->laser.bus, false);
        for (size_t i = 0; r >= 0 && i < rc->n_cameras; i++)
                r = check_bus(yc, rc, "cameras", i, rc->cameras[i].name, rc->cameras[i].bus, true);
        return r;
}

static int parse_root(struct yconf *yc, struct rig_config *rc)
{
        static const char *const keys[] = {"rig",   "profiles", "buses", "axes", "lamps",
                                           "laser", "cameras",  "scene", NULL};
        struct fy_node *root = yconf_root(yc), *laser;
        int r;

        if (!root)
                return yconf_error(yc, NULL, NULL, "the rig file is empty");
        if ((r = yconf_check_keys(yc, root, keys)) < 0 ||
            (r = yconf_str_req(yc, root, "rig", rc->name, sizeof(rc->name))) < 0)
                return r;
        rigconf_default_profile(&rc->profiles[0]);
        if ((r = parse_section(yc, root, "profiles", rc->profiles + 1, sizeof(rc->profiles[0]),
                               ELEMENTSOF(rc->profiles) - 1, &rc->n_profiles,
                               (parse_fn)parse_profile)) < 0)
                return r;
        rc->n_profiles += 1; /* the built-in default comes first */
        if ((r = parse_section(yc, root, "buses", rc->buses, sizeof(rc->buses[0]), RIG_MAX_BUSES,
                               &rc->n_buses, (parse_fn)parse_bus)) < 0 ||
            (r = parse_section(yc, root, "axes", rc->axes, sizeof(rc->axes[0]), RIG_MAX_AXES,
                               &rc->n_axes, (parse_fn)parse_axis)) < 0 ||
            (r = parse_section(yc, root, "lamps", rc->lamps, sizeof(rc->lamps[0]), RIG_MAX_LAMPS,
                               &rc->n_lamps, (parse_fn)parse_lamp)) < 0 ||
            (r = parse_section(yc, root, "cameras", rc->cameras, sizeof(rc->cameras[0]),
                               RIG_MAX_CAMERAS, &rc->n_cameras, (parse_fn)parse_camera)) < 0)
                return r;
        laser = yconf_get(root, "laser");
        if (laser) {
                if ((r = parse_laser(yc, laser, &rc->laser)) < 0)
                        return r;
                rc->has_laser = true;
        }
        if ((r = check_unique(yc, rc)) < 0)
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
        if (getdelim(&buf, &len, '\0', f) < 0 && !feof(f))
                return -errno;
        if (!buf && !(buf = strdup("")))
                return -ENOMEM;
        *ret = TAKE_PTR(buf);
        return 0;
}

int rigconf_load(const char *path, struct rig_config **ret, char *err, size_t errlen)
{
        struct rig_config *rc = calloc(1, sizeof(*rc));
        int r;

        if (!rc)
                return -ENOMEM;
        snprintf(rc->path, sizeof(rc->path), "%s", path);
        r = read_text(path, &rc->text);
        if (r < 0) {
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                rigconf_free(rc);
                return r;
        }
        r = yconf_open_string(&rc->yc, rc->path, rc->text, err, errlen);
        if (r >= 0)
                r = parse_root(&rc->yc, rc);
        if (r < 0) {
                rigconf_free(rc);
                return r;
        }
        *ret = rc;
        return 0;
}

struct rig_config *rigconf_free(struct rig_config *rc)
{
        if (!rc)
                return NULL;
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
