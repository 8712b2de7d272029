/* control.c - gonio-sim's control channel: state, geometry, fault injection (see
 * control.h; protocol in docs/sim.md). */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "common/cleanup.h"
#include "sim/control.h"

struct cam_faults {
        long drop, disconnect; /* render requests still to fail that way */
};

struct sim_control {
        const struct rig_config *rc;
        struct sim_scene *scene;
        struct sim_emu *emu;
        struct cam_faults faults[RIG_MAX_CAMERAS];
};

/* ---- JSON of the rig ---- */

static json_t *reals(const double *v, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                if (json_array_append_new(a, json_real(v[i])) < 0) {
                        json_decref(a);
                        return NULL;
                }
        return a;
}

static bool lamp_lit(const struct gn_pose *st, size_t i)
{
        return i < GN_POSE_MAX_LAMPS && (st->lamps & (UINT32_C(1) << i));
}

json_t *sim_pose_json(const struct rig_config *rc, const struct gn_pose *st)
{
        json_t *o = json_pack("{s:o, s:o, s:b}", "lamps", json_array(), "lasers", json_array(),
                              "laser", st->lasers != 0);
        int r = o ? 0 : -ENOMEM;

        for (size_t i = 0; r >= 0 && i < rc->n_lamps; i++)
                r = json_array_append_new(json_object_get(o, "lamps"),
                                          json_boolean(lamp_lit(st, i)));
        for (size_t i = 0; r >= 0 && i < rc->n_lasers; i++)
                r = json_array_append_new(json_object_get(o, "lasers"),
                                          json_boolean(st->lasers >> i & 1));
        for (int i = 0; r >= 0 && i < GN_ROLE_COUNT; i++) {
                json_t *deg = gn_pose_has(st, i) ? json_real(st->deg[i]) : json_null();
                r = json_object_set_new(o, gn_role_name(i), deg);
        }
        if (r < 0)
                json_decref(TAKE_PTR(o));
        return o;
}

static json_t *camera_json(struct sim_control *c, const struct gn_pose *st, int ci)
{
        struct sim_cam_geom g;

        if (sim_camera_geom(c->scene, st, ci, &g) < 0)
                return NULL;
        return json_pack("{s:s, s:i, s:i, s:f, s:f, s:f, s:f, s:o, s:o, s:o}", "name",
                         c->rc->cameras[ci].name, "width", g.width, "height", g.height, "fx", g.fx,
                         "fy", g.fy, "cx", g.cx, "cy", g.cy, "dist", reals(g.dist, 5), "R",
                         reals(g.R, 9), "t", reals(g.t, 3));
}

static json_t *lamp_json(struct sim_control *c, const struct gn_pose *st, int i)
{
        double p[3];

        if (sim_lamp_position(c->scene, st, i, p) < 0)
                return NULL;
        return json_pack("{s:s, s:o, s:b}", "name", c->rc->lamps[i].name, "position", reals(p, 3),
                         "on", lamp_lit(st, (size_t)i));
}

/* Laser i's plane and state; null when the rig has no laser i. */
static json_t *laser_json(struct sim_control *c, const struct gn_pose *st, int i)
{
        double n[3], d;

        if (sim_laser_plane(c->scene, i, n, &d) < 0)
                return json_null();
        return json_pack("{s:s, s:o, s:f, s:b}", "name", c->rc->lasers[i].name, "n", reals(n, 3),
                         "d", d, "on", (st->lasers >> i & 1) != 0);
}

/* ---- commands ---- */

static int do_state(struct sim_control *c, struct sim_req *rq, json_t **reply)
{
        struct gn_pose st;

        (void)rq;
        sim_emu_snapshot(c->emu, &st);
        *reply = json_pack("{s:b, s:o}", "ok", 1, "state", sim_pose_json(c->rc, &st));
        return 0;
}

static int do_geometry(struct sim_control *c, struct sim_req *rq, json_t **reply)
{
        struct gn_pose st;
        json_t *cams = json_array(), *lamps = json_array(), *lasers = json_array();
        int r = 0;

        sim_emu_snapshot(c->emu, &st);
        for (size_t i = 0; r >= 0 && i < c->rc->n_cameras; i++)
                r = json_array_append_new(cams, camera_json(c, &st, (int)i));
        for (size_t i = 0; r >= 0 && i < c->rc->n_lamps; i++)
                r = json_array_append_new(lamps, lamp_json(c, &st, (int)i));
        for (size_t i = 0; r >= 0 && i < c->rc->n_lasers; i++)
                r = json_array_append_new(lasers, laser_json(c, &st, (int)i));
        if (r < 0) {
                json_decref(cams);
                json_decref(lamps);
                json_decref(lasers);
                return sim_req_fail(rq, EIO, "geometry of the scene unavailable");
        }
        *reply = json_pack("{s:b, s:o, s:o, s:o, s:o, s:o}", "ok", 1, "state",
                           sim_pose_json(c->rc, &st), "cameras", cams, "lamps", lamps, "lasers",
                           lasers, "laser", laser_json(c, &st, 0));
        return 0;
}

static int inject_camera(struct sim_control *c, struct sim_req *rq, const char *fault)
{
        long count = 1;
        int ci = 0;

        int r = sim_req_camera(rq, c->rc, &ci);
        if (r >= 0)
                r = sim_req_int(rq, "count", 0, 1000000, &count);
        if (r < 0)
                return r;
        struct cam_faults *cf = &c->faults[ci];
        if (strcmp(fault, "drop") == 0)
                cf->drop = count;
        else if (strcmp(fault, "disconnect") == 0)
                cf->disconnect = count;
        else if (strcmp(fault, "none") == 0)
                *cf = (struct cam_faults){0};
        else
                return sim_req_fail(rq, EINVAL, "camera faults are drop, disconnect, none");
        return 0;
}

static int inject_modbus(struct sim_control *c, struct sim_req *rq, const char *fault)
{
        static const char *const names[] = {
                [SIM_FAULT_NONE] = "none",   [SIM_FAULT_TIMEOUT] = "timeout",
                [SIM_FAULT_CRC] = "crc",     [SIM_FAULT_EXCEPTION] = "exception",
                [SIM_FAULT_STALL] = "stall", [SIM_FAULT_SHORT] = "short",
                [SIM_FAULT_LATE] = "late",   [SIM_FAULT_ERROR] = "error",
        };
        const char *bus = json_string_value(json_object_get(rq->req, "bus"));
        long unit = -1;
        size_t f;

        int r = sim_req_int(rq, "unit", 0, 255, &unit);
        if (r < 0)
                return r;
        if (!bus || unit < 0)
                return sim_req_fail(rq, EINVAL, "inject needs 'camera', or 'bus' and 'unit'");
        for (f = 0; f < ELEMENTSOF(names) && strcmp(names[f], fault) != 0; f++)
                ;
        if (f == ELEMENTSOF(names))
                return sim_req_fail(
                        rq, EINVAL,
                        "device faults are none, timeout, crc, exception, stall, short (Modbus), "
                        "late, error (G-code)");
        r = sim_emu_inject(c->emu, bus, (int)unit, (enum sim_fault)f);
        if (r == -ENOENT)
                return sim_req_fail(rq, ENOENT, "no emulated device at bus '%s' unit %ld", bus,
                                    unit);
        if (r < 0)
                return sim_req_fail(rq, -r, "fault '%s' does not apply to bus '%s' unit %ld", fault,
                                    bus, unit);
        return 0;
}

/* {"cmd": "unplug", "bus": NAME, "ms": N}: a Modbus RTU line pulled out and put back. */
static int do_unplug(struct sim_control *c, struct sim_req *rq, json_t **reply)
{
        const char *bus = json_string_value(json_object_get(rq->req, "bus"));
        long ms = 0;
        int r = sim_req_int(rq, "ms", 1, 600000, &ms);

        if (r < 0)
                return r;
        if (!bus || ms <= 0)
                return sim_req_fail(rq, EINVAL, "unplug needs 'bus' and 'ms' (1..600000)");
        r = sim_emu_unplug(c->emu, bus, (int)ms);
        if (r == -ENOENT)
                return sim_req_fail(rq, ENOENT, "no emulated Modbus RTU line '%s'", bus);
        if (r < 0)
                return sim_req_fail(rq, -r, "line '%s' is unplugged already", bus);
        *reply = json_pack("{s:b}", "ok", 1);
        return 0;
}

static int do_inject(struct sim_control *c, struct sim_req *rq, json_t **reply)
{
        const char *fault = json_string_value(json_object_get(rq->req, "fault"));

        if (!fault)
                return sim_req_fail(rq, EINVAL, "'fault' must be a string");
        int r = json_object_get(rq->req, "camera") ? inject_camera(c, rq, fault)
                                                   : inject_modbus(c, rq, fault);
        if (r >= 0)
                *reply = json_pack("{s:b}", "ok", 1);
        return r;
}

int sim_control_handle(struct sim_control *c, struct sim_req *rq, const char *cmd, json_t **reply)
{
        static const struct {
                const char *name;
                int (*fn)(struct sim_control *c, struct sim_req *rq, json_t **reply);
        } cmds[] = {
                {"state", do_state},
                {"geometry", do_geometry},
                {"inject", do_inject},
                {"unplug", do_unplug},
        };

        *reply = NULL;
        for (size_t i = 0; i < ELEMENTSOF(cmds); i++)
                if (strcmp(cmds[i].name, cmd) == 0) {
                        int r = cmds[i].fn(c, rq, reply);
                        if (r >= 0 && !*reply)
                                return sim_req_fail(rq, ENOMEM, "out of memory");
                        return r;
                }
        return sim_req_fail(rq, EINVAL, "unknown cmd '%s'", cmd);
}

int sim_control_camera_fault(struct sim_control *c, int cam)
{
        struct cam_faults *cf = &c->faults[cam];

        if (cf->disconnect > 0) {
                cf->disconnect--;
                return -ECONNABORTED;
        }
        if (cf->drop > 0) {
                cf->drop--;
                return -ETIMEDOUT;
        }
        return 0;
}

int sim_control_new(const struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                    struct sim_control **ret)
{
        if (!rc || !scene || !emu || !ret)
                return -EINVAL;
        struct sim_control *c = calloc(1, sizeof *c);
        if (!c)
                return -ENOMEM;
        *c = (struct sim_control){.rc = rc, .scene = scene, .emu = emu};
        *ret = c;
        return 0;
}

struct sim_control *sim_control_free(struct sim_control *c)
{
        free(c);
        return NULL;
}
