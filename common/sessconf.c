/* sessconf.c - loads and validates a session file against the rig (docs/sessions.md).
 *
 * The parse is strict like the rig file's: unknown keys, missing required keys, names the
 * rig does not have, sweeps of roles it has no axis for or outside an axis's soft limits,
 * angles twice, negative or out-of-range exposures, bad brackets are errors that name the
 * file, the line and the key (dotted for nested keys: 'sweep.turntable'). Defaults are
 * filled in here, so the planner reads plain values. */
#include <errno.h>
#include <fcntl.h>
#include <libfyaml.h>
#include <limits.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cleanup.h"
#include "fileio.h"
#include "sessconf.h"

/* Largest session file read. */
#define SESS_FILE_MAX (1u << 20)
/* Two angles closer than this (degrees) are one. */
#define SESS_ANGLE_EPS 1e-6

/* What a parse works on. */
struct sparse {
        struct yconf yc;
        const struct rig_config *rc;
        struct session_conf *sc;
};

int sessconf_exposure_us(const struct rig_camera_conf *c, int exposure_us, double ev)
{
        return (int)lround((exposure_us > 0 ? exposure_us : c->exposure_us) * exp2(ev));
}

/* Where an error about key of map points: its value, or the key itself when the value has
 * no line of its own (an empty list or mapping). */
static struct fy_node *at(struct fy_node *map, const char *key)
{
        struct fy_node *v = yconf_get(map, key);

        if (v && yconf_line(v) > 0)
                return v;
        return fy_node_mapping_lookup_key_by_string(map, key, FY_NT) ?: map;
}

/* The number in scalar node n (key names it in messages). Returns 0 or -EINVAL. */
static int read_number(struct yconf *yc, struct fy_node *n, const char *key, double *out)
{
        const char *text = fy_node_get_type(n) == FYNT_SCALAR ? fy_node_get_scalar0(n) : NULL;
        char *end;

        if (!text)
                return yconf_error(yc, n, key, "expected a number");
        errno = 0;
        *out = strtod(text, &end);
        if (errno || end == text || *end || !isfinite(*out))
                return yconf_error(yc, n, key, "'%s' is not a number", text);
        return 0;
}

/* Adds angle deg (read at node n) to the sweep sw of axis ax: normalised on a continuous
 * axis, within the soft limits otherwise, and not twice. A range's last angle that comes
 * back to its first on a continuous axis (a full turn, wrap) is dropped. */
static int sweep_add(struct yconf *yc, struct fy_node *n, const char *key,
                     const struct rig_axis_conf *ax, struct sess_sweep *sw, double deg, bool wrap)
{
        if (ax->continuous)
                deg = fmod(fmod(deg, 360.0) + 360.0, 360.0);
        else if (deg < ax->min_deg - SESS_ANGLE_EPS || deg > ax->max_deg + SESS_ANGLE_EPS)
                return yconf_error(yc, n, key,
                                   "%g deg is outside the soft limits [%g, %g] of axis '%s'", deg,
                                   ax->min_deg, ax->max_deg, ax->name);
        for (size_t i = 0; i < sw->n; i++) {
                if (gn_angle_distance(sw->deg[i], deg) > SESS_ANGLE_EPS ||
                    (!ax->continuous && fabs(sw->deg[i] - deg) > SESS_ANGLE_EPS))
                        continue;
                if (wrap && i == 0)
                        return 0;
                return yconf_error(yc, n, key, "angle %g deg is listed twice%s", deg,
                                   ax->continuous ? " (angles are taken modulo 360)" : "");
        }
        if (sw->n >= SESS_MAX_ANGLES)
                return yconf_error(yc, n, key, "more than %d angles", SESS_MAX_ANGLES);
        sw->deg[sw->n++] = deg;
        return 0;
}

/* A sweep given as {from, to, step}: from, from + step, ... up to to (inclusive when a
 * step lands on it); step > 0 whichever way from and to go. */
static int sweep_range(struct yconf *yc, struct fy_node *m, const char *key,
                       const struct rig_axis_conf *ax, struct sess_sweep *sw)
{
        static const char *const keys[] = {"from", "to", "step", NULL};
        const char *names[] = {"from", "to", "step"};
        double v[3], n;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0)
                return r;
        for (int i = 0; i < 3; i++) {
                struct fy_node *x = yconf_get(m, names[i]);

                if (!x)
                        return yconf_error(yc, m, key, "'%s' is missing (from, to, step)",
                                           names[i]);
                if ((r = read_number(yc, x, key, &v[i])) < 0)
                        return r;
        }
        if (!(v[2] > 0))
                return yconf_error(yc, yconf_get(m, "step"), key, "step must be > 0");
        n = floor(fabs(v[1] - v[0]) / v[2] + 1e-9);
        if (n >= SESS_MAX_ANGLES)
                return yconf_error(yc, yconf_get(m, "step"), key, "more than %d angles",
                                   SESS_MAX_ANGLES);
        for (int i = 0; i <= (int)n; i++) {
                double deg = v[0] + copysign(i * v[2], v[1] - v[0]);
                struct fy_node *at = yconf_get(m, i == 0 ? "from" : "to");

                if ((r = sweep_add(yc, at, key, ax, sw, deg, i > 0 && i == (int)n)) < 0)
                        return r;
        }
        return 0;
}

/* A sweep given as a list of angles. */
static int sweep_list(struct yconf *yc, struct fy_node *v, const char *key,
                      const struct rig_axis_conf *ax, struct sess_sweep *sw)
{
        int n = yconf_seq_len(yc, v, key), r;
        double deg;

        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(v, i);

                if ((r = read_number(yc, item, key, &deg)) < 0 ||
                    (r = sweep_add(yc, item, key, ax, sw, deg, false)) < 0)
                        return r;
        }
        return 0;
}

/* The sweep of one role: a list of angles, one angle, or a {from, to, step} range. */
static int sweep_role(struct sparse *p, struct fy_node *v, enum gn_role role)
{
        struct yconf *yc = &p->yc;
        struct sess_sweep *sw = &p->sc->sweep[role];
        int ax = rigconf_axis_of_role(p->rc, role), r;
        char key[48];
        double deg;

        snprintf(key, sizeof(key), "sweep.%s", gn_role_name(role));
        if (ax < 0)
                return yconf_error(yc, v, key, "rig '%s' has no axis of role '%s'", p->rc->name,
                                   gn_role_name(role));
        if (!(sw->deg = calloc(SESS_MAX_ANGLES, sizeof(double))))
                return -ENOMEM;
        switch (fy_node_get_type(v)) {
        case FYNT_MAPPING:
                r = sweep_range(yc, v, key, &p->rc->axes[ax], sw);
                break;
        case FYNT_SEQUENCE:
                r = sweep_list(yc, v, key, &p->rc->axes[ax], sw);
                break;
        default:
                r = read_number(yc, v, key, &deg);
                if (r >= 0)
                        r = sweep_add(yc, v, key, &p->rc->axes[ax], sw, deg, false);
        }
        return r < 0 ? r : 0;
}

/* The role of key k of a map keyed by role (its key named in messages as
 * "parent.role"), or an error naming the roles. */
static int role_key(struct yconf *yc, struct fy_node *k, const char *parent)
{
        const char *name = fy_node_get_scalar0(k);
        int role = gn_role_from_name(name);
        char key[48];

        if (role >= 0)
                return role;
        snprintf(key, sizeof(key), "%s.%s", parent, name ?: "?");
        return yconf_error(yc, k, key, "unknown key (turntable, light_arm or camera_arm)");
}

static int parse_sweeps(struct sparse *p, struct fy_node *root)
{
        struct fy_node *m = yconf_get(root, "sweep");
        struct fy_node_pair *pair;
        void *iter = NULL;
        int r;

        if (!m)
                return 0;
        if (fy_node_get_type(m) != FYNT_MAPPING)
                return yconf_error(&p->yc, m, "sweep", "expected a mapping of roles to angles");
        while ((pair = fy_node_mapping_iterate(m, &iter))) {
                struct fy_node *k = fy_node_pair_key(pair), *v = fy_node_pair_value(pair);
                int role = role_key(&p->yc, k, "sweep");
                char key[48];

                if (role < 0)
                        return role;
                snprintf(key, sizeof(key), "sweep.%s", gn_role_name(role));
                if (fy_node_get_type(v) == FYNT_SEQUENCE && fy_node_sequence_item_count(v) == 0)
                        return yconf_error(&p->yc, k, key, "an empty sweep (leave the role out)");
                if ((r = sweep_role(p, v, role)) < 0)
                        return r;
        }
        return 0;
}

/* The rig's cameras or lamps, for name lookups. */
struct devices {
        const char *kind; /* "camera", "lamp" */
        size_t n;
        const char *(*name)(const struct rig_config *rc, size_t i);
};

static const char *camera_name(const struct rig_config *rc, size_t i)
{
        return rc->cameras[i].name;
}

static const char *lamp_name(const struct rig_config *rc, size_t i)
{
        return rc->lamps[i].name;
}

static const char *laser_name(const struct rig_config *rc, size_t i)
{
        return rc->lasers[i].name;
}

/* Index of the device named name, or an error at n listing the known names. */
static int device_index(struct sparse *p, const struct devices *d, struct fy_node *n,
                        const char *key, const char *name)
{
        char names[256] = "";
        size_t o = 0;

        for (size_t i = 0; i < d->n; i++) {
                if (strcmp(d->name(p->rc, i), name) == 0)
                        return i;
                if (o < sizeof(names))
                        o += snprintf(names + o, sizeof(names) - o, "%s%s", i ? ", " : "",
                                      d->name(p->rc, i));
        }
        return yconf_error(&p->yc, n, key, "unknown %s '%s' (rig '%s' has: %s)", d->kind, name,
                           p->rc->name, d->n ? names : "none");
}

/* A set of devices: "all" or a list of names, into the bit set *mask (which keeps its
 * default when key is absent). */
static int parse_names(struct sparse *p, struct fy_node *root, const char *key,
                       const struct devices *d, uint32_t *mask)
{
        struct fy_node *v = yconf_get(root, key);
        const char *s;
        int n;

        if (!v)
                return 0;
        s = fy_node_get_type(v) == FYNT_SCALAR ? fy_node_get_scalar0(v) : NULL;
        if (s && strcmp(s, "all") == 0)
                return *mask = d->n ? (uint32_t)((1ull << d->n) - 1) : 0, 0;
        if ((n = yconf_seq_len(&p->yc, v, key)) < 0)
                return n;
        *mask = 0;
        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(v, i);
                const char *name =
                        fy_node_get_type(item) == FYNT_SCALAR ? fy_node_get_scalar0(item) : NULL;
                int k = name ? device_index(p, d, item, key, name)
                             : yconf_error(&p->yc, item, key, "expected a %s name", d->kind);

                if (k < 0)
                        return k;
                if (*mask & (1u << k))
                        return yconf_error(&p->yc, item, key, "%s '%s' is listed twice", d->kind,
                                           name);
                *mask |= 1u << k;
        }
        return 0;
}

/* The key `laser`: false (none), true or `all` (one frame, every laser lit together), `each`
 * (one frame per laser, each alone), a name or a list of names (one frame, those lit
 * together). */
static int parse_laser(struct sparse *p, struct fy_node *root)
{
        const struct devices d = {"laser", p->rc->n_lasers, laser_name};
        struct fy_node *v = yconf_get(root, "laser");
        const char *s = v && fy_node_get_type(v) == FYNT_SCALAR ? fy_node_get_scalar0(v) : NULL;
        struct session_conf *sc = p->sc;
        uint32_t set = rigconf_all_lasers(p->rc);
        int k;

        if (!v || (s && yconf_bool_word(s) == 0))
                return 0;
        if (!p->rc->n_lasers)
                return yconf_error(&p->yc, v, "laser", "rig '%s' has no laser", p->rc->name);
        if (s && strcmp(s, "each") == 0) {
                for (size_t i = 0; i < p->rc->n_lasers; i++)
                        sc->laser_shots[sc->n_laser_shots++] = UINT32_C(1) << i;
                return 0;
        }
        if (!s && (k = parse_names(p, root, "laser", &d, &set)) < 0)
                return k;
        if (s && yconf_bool_word(s) < 0 && strcmp(s, "all") != 0) {
                if ((k = device_index(p, &d, v, "laser", s)) < 0)
                        return k;
                set = UINT32_C(1) << k;
        }
        if (set)
                sc->laser_shots[sc->n_laser_shots++] = set;
        return 0;
}

static int parse_devices(struct sparse *p, struct fy_node *root)
{
        const struct devices cams = {"camera", p->rc->n_cameras, camera_name};
        const struct devices lamps = {"lamp", p->rc->n_lamps, lamp_name};
        struct session_conf *sc = p->sc;
        int r;

        sc->cameras = p->rc->n_cameras ? (uint32_t)((1ull << p->rc->n_cameras) - 1) : 0;
        sc->lamps = p->rc->n_lamps ? (uint32_t)((1ull << p->rc->n_lamps) - 1) : 0;
        if ((r = parse_names(p, root, "cameras", &cams, &sc->cameras)) < 0 ||
            (r = parse_names(p, root, "lamps", &lamps, &sc->lamps)) < 0 ||
            (r = parse_laser(p, root)) < 0 ||
            (r = yconf_bool(&p->yc, root, "unlit", &sc->unlit)) < 0)
                return r;
        sc->flat_lamps = sc->lamps ?: (uint32_t)((1ull << p->rc->n_lamps) - 1);
        if ((r = parse_names(p, root, "flat_lamps", &lamps, &sc->flat_lamps)) < 0)
                return r;
        if (!sc->cameras)
                return yconf_error(&p->yc, at(root, "cameras"), "cameras",
                                   "no camera to capture with");
        if (!sc->lamps && !sc->n_laser_shots && !sc->unlit)
                return yconf_error(&p->yc, at(root, "lamps"), "lamps",
                                   "nothing to capture: no lamp, no laser and no unlit frame");
        return 0;
}

/* exposure_us and gain: 0 or absent for each camera's default, else within the rig's
 * ranges. */
static int parse_exposure(struct sparse *p, struct fy_node *root)
{
        struct yconf *yc = &p->yc;
        struct session_conf *sc = p->sc;
        long exp = 0;
        int r;

        if ((r = yconf_int(yc, root, "exposure_us", LONG_MIN, LONG_MAX, &exp)) < 0 ||
            (r = yconf_double(yc, root, "gain", -INFINITY, INFINITY, &sc->gain)) < 0)
                return r;
        if (exp < 0)
                return yconf_error(yc, yconf_get(root, "exposure_us"), "exposure_us",
                                   "%ld: an exposure cannot be negative (0: each camera's "
                                   "default)",
                                   exp);
        if (exp > RIG_EXPOSURE_US_MAX)
                return yconf_error(yc, yconf_get(root, "exposure_us"), "exposure_us",
                                   "%ld us is longer than %d us", exp, RIG_EXPOSURE_US_MAX);
        sc->exposure_us = (int)exp;
        if (sc->gain != 0 && (sc->gain < RIG_GAIN_MIN || sc->gain > RIG_GAIN_MAX))
                return yconf_error(yc, yconf_get(root, "gain"), "gain",
                                   "%g is out of range [%g, %g] (0: each camera's default)",
                                   sc->gain, RIG_GAIN_MIN, RIG_GAIN_MAX);
        return 0;
}

/* Each session camera's exposure at ev (read at n) must be one the rig allows. */
static int check_bracket(struct sparse *p, struct fy_node *n, double ev)
{
        for (size_t c = 0; c < p->rc->n_cameras; c++) {
                const struct rig_camera_conf *cam = &p->rc->cameras[c];
                double us = (p->sc->exposure_us ?: cam->exposure_us) * exp2(ev);

                if (!(p->sc->cameras & (1u << c)) ||
                    (us >= RIG_EXPOSURE_US_MIN && us <= RIG_EXPOSURE_US_MAX))
                        continue;
                return yconf_error(&p->yc, n, "brackets",
                                   "%+g EV gives camera '%s' an exposure of %.0f us, outside "
                                   "[%d, %d]",
                                   ev, cam->name, us, RIG_EXPOSURE_US_MIN, RIG_EXPOSURE_US_MAX);
        }
        return 0;
}

/* brackets: a list of 1 to SESS_MAX_BRACKETS distinct EVs within +-SESS_MAX_EV. */
static int parse_brackets(struct sparse *p, struct fy_node *root)
{
        struct fy_node *v = yconf_get(root, "brackets");
        struct session_conf *sc = p->sc;
        int n, r;

        sc->n_brackets = 1;
        sc->bracket_ev[0] = 0;
        if (!v)
                return check_bracket(p, root, 0);
        if ((n = yconf_seq_len(&p->yc, v, "brackets")) < 0)
                return n;
        if (n < 1 || n > SESS_MAX_BRACKETS)
                return yconf_error(&p->yc, at(root, "brackets"), "brackets",
                                   "expected 1 to %d EVs, got %d", SESS_MAX_BRACKETS, n);
        for (int i = 0; i < n; i++) {
                struct fy_node *item = yconf_seq_item(v, i);
                double ev;

                if ((r = read_number(&p->yc, item, "brackets", &ev)) < 0)
                        return r;
                if (fabs(ev) > SESS_MAX_EV)
                        return yconf_error(&p->yc, item, "brackets",
                                           "%+g EV is out of range [-%d, +%d]", ev, SESS_MAX_EV,
                                           SESS_MAX_EV);
                for (int j = 0; j < i; j++)
                        if (sc->bracket_ev[j] == ev)
                                return yconf_error(&p->yc, item, "brackets",
                                                   "%+g EV is listed twice", ev);
                if ((r = check_bracket(p, item, ev)) < 0)
                        return r;
                sc->bracket_ev[i] = ev;
        }
        sc->n_brackets = n;
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

/* settle_ms: { role: ms } for the roles the rig has an axis for. */
static int parse_settle(struct sparse *p, struct fy_node *root)
{
        struct fy_node *m = yconf_get(root, "settle_ms");
        struct fy_node_pair *pair;
        void *iter = NULL;

        if (m && fy_node_get_type(m) != FYNT_MAPPING)
                return yconf_error(&p->yc, m, "settle_ms", "expected a mapping of roles to ms");
        while (m && (pair = fy_node_mapping_iterate(m, &iter))) {
                struct fy_node *k = fy_node_pair_key(pair), *v = fy_node_pair_value(pair);
                int role = role_key(&p->yc, k, "settle_ms"), r;
                char key[48];
                double ms;

                if (role < 0)
                        return role;
                snprintf(key, sizeof(key), "settle_ms.%s", gn_role_name(role));
                if (rigconf_axis_of_role(p->rc, role) < 0)
                        return yconf_error(&p->yc, k, key, "rig '%s' has no axis of role '%s'",
                                           p->rc->name, gn_role_name(role));
                if ((r = read_number(&p->yc, v, key, &ms)) < 0)
                        return r;
                if (ms < 0 || ms > 60000 || ms != floor(ms))
                        return yconf_error(&p->yc, v, key, "%g: whole ms in [0, 60000]", ms);
                p->sc->settle_ms[role] = (int)ms;
        }
        return 0;
}

static int parse_frames(struct sparse *p, struct fy_node *root)
{
        struct yconf *yc = &p->yc;
        struct session_conf *sc = p->sc;
        int r;

        sc->dark_max_age_s = 86400;
        if ((r = read_int(yc, root, "dark_frames", 0, SESS_MAX_FRAMES, &sc->dark_frames)) < 0 ||
            (r = read_int(yc, root, "dark_max_age_s", 0, INT_MAX, &sc->dark_max_age_s)) < 0 ||
            (r = read_int(yc, root, "flat_frames", 0, SESS_MAX_FRAMES, &sc->flat_frames)) < 0)
                return r;
        if (sc->flat_frames > 0 && !sc->flat_lamps)
                return yconf_error(yc, at(root, "flat_lamps"), "flat_lamps",
                                   "flat frames need a lamp");
        return 0;
}

static int parse_skips(struct sparse *p, struct fy_node *root)
{
        struct yconf *yc = &p->yc;
        struct session_conf *sc = p->sc;
        int r;

        sc->skip_occluded = sc->skip_glare = true;
        if ((r = yconf_bool(yc, root, "skip_occluded", &sc->skip_occluded)) < 0 ||
            (r = yconf_bool(yc, root, "skip_glare", &sc->skip_glare)) < 0 ||
            (r = yconf_double(yc, root, "occlusion_deg", 0, 90, &sc->occlusion_deg)) < 0)
                return r;
        return 0;
}

/* metadata: any mapping, kept as one line of JSON. */
static int parse_metadata(struct sparse *p, struct fy_node *root)
{
        struct fy_node *m = yconf_get(root, "metadata");

        if (m && fy_node_get_type(m) != FYNT_MAPPING)
                return yconf_error(&p->yc, m, "metadata", "expected a mapping");
        p->sc->metadata_json =
                m ? fy_emit_node_to_string(m, FYECF_MODE_JSON_ONELINE | FYECF_WIDTH_INF |
                                                      FYECF_NO_ENDING_NEWLINE)
                  : strdup("{}");
        return p->sc->metadata_json ? 0 : -ENOMEM;
}

/* A name for files and records: not empty, no '/', no space or control character. */
static int check_name(struct yconf *yc, struct fy_node *n, const char *key, const char *s)
{
        for (const char *c = s; *c; c++)
                if (*c == '/' || (unsigned char)*c <= ' ')
                        return yconf_error(yc, n, key,
                                           "'%s': names may not contain '/', spaces or control "
                                           "characters",
                                           s);
        return s[0] ? 0 : yconf_error(yc, n, key, "must not be empty");
}

/* name (default: the file's basename without .yaml or .yml) and dataset (required). */
static int parse_names_of_session(struct sparse *p, struct fy_node *root)
{
        struct yconf *yc = &p->yc;
        struct session_conf *sc = p->sc;
        const char *base = strrchr(sc->path, '/') ? strrchr(sc->path, '/') + 1 : sc->path;
        size_t len = strcspn(base, ".");
        int r;

        snprintf(sc->name, sizeof(sc->name), "%.*s", (int)MIN(len, sizeof(sc->name) - 1), base);
        if ((r = yconf_str(yc, root, "name", sc->name, sizeof(sc->name))) < 0 ||
            (r = check_name(yc, yconf_get(root, "name") ?: root, "name", sc->name)) < 0 ||
            (r = yconf_str_req(yc, root, "dataset", sc->dataset, sizeof(sc->dataset))) < 0 ||
            (r = check_name(yc, yconf_get(root, "dataset"), "dataset", sc->dataset)) < 0)
                return r;
        return 0;
}

static int parse_root(struct sparse *p)
{
        static const char *const keys[] = {
                "name",          "dataset",        "sweep",         "cameras",    "lamps",
                "exposure_us",   "gain",           "brackets",      "laser",      "unlit",
                "dark_frames",   "dark_max_age_s", "flat_frames",   "flat_lamps", "settle_ms",
                "skip_occluded", "skip_glare",     "occlusion_deg", "metadata",   NULL};
        struct fy_node *root = yconf_root(&p->yc);
        int r;

        if (!root || (fy_node_get_type(root) == FYNT_SCALAR && !*fy_node_get_scalar0(root)))
                return yconf_error(&p->yc, NULL, NULL, "the session file is empty");
        if ((r = yconf_check_keys(&p->yc, root, keys)) < 0 ||
            (r = parse_names_of_session(p, root)) < 0 || (r = parse_sweeps(p, root)) < 0 ||
            (r = parse_devices(p, root)) < 0 || (r = parse_exposure(p, root)) < 0 ||
            (r = parse_brackets(p, root)) < 0 || (r = parse_frames(p, root)) < 0 ||
            (r = parse_settle(p, root)) < 0 || (r = parse_skips(p, root)) < 0 ||
            (r = parse_metadata(p, root)) < 0)
                return r;
        return 0;
}

int sessconf_load_string(const char *path, const char *text, const struct rig_config *rc,
                         struct session_conf **ret, char *err, size_t errlen)
{
        struct sparse p = {.rc = rc};
        int r;

        if (!path || !text || !rc || !ret)
                return -EINVAL;
        if (!(p.sc = calloc(1, sizeof(*p.sc))) || !(p.sc->text = strdup(text))) {
                sessconf_free(p.sc);
                return -ENOMEM;
        }
        snprintf(p.sc->path, sizeof(p.sc->path), "%s", path);
        /* libfyaml builds no document from nothing: say what is wrong */
        r = yconf_open_string(&p.yc, p.sc->path, text[strspn(text, " \t\r\n")] ? text : "---", err,
                              errlen);
        if (r >= 0)
                r = parse_root(&p);
        yconf_close(&p.yc);
        if (r < 0) {
                sessconf_free(p.sc);
                return r;
        }
        *ret = p.sc;
        return 0;
}

int sessconf_load(const char *path, const struct rig_config *rc, struct session_conf **ret,
                  char *err, size_t errlen)
{
        _cleanup_free_ void *text = NULL;
        size_t len;
        int r = gn_read_file_at(AT_FDCWD, path, SESS_FILE_MAX, &text, &len);

        if (r < 0) {
                snprintf(err, errlen, "%s: %s", path, strerror(-r));
                return r;
        }
        return sessconf_load_string(path, text, rc, ret, err, errlen);
}

struct session_conf *sessconf_free(struct session_conf *sc)
{
        if (!sc)
                return NULL;
        for (int i = 0; i < GN_ROLE_COUNT; i++)
                free(sc->sweep[i].deg);
        free(sc->metadata_json);
        free(sc->text);
        free(sc);
        return NULL;
}
