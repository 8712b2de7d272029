/* test-gcode-proto.c - pure G-code line handling (drivers/axis/gcode/proto.c and
 * drivers/switch/gcode/proto.c): every kind of reply line of Horus 0.2 and GRBL 1.1, status
 * reports of both formats, move and laser command lines, wrapping, the shortest way round,
 * and the backend maps as a rig file gives them. */
#include <errno.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "drivers/axis/gcode/proto.h"
#include "drivers/registry.h"
#include "drivers/switch/gcode/proto.h"
#include "tests/test.h"

static struct gc_line parse(const char *s)
{
        struct gc_line l;

        CHECK_INT(gc_parse_line(s, &l), 0);
        return l;
}

static void test_lines(void)
{
        struct gc_line l;

        CHECK_INT(parse("ok").kind, GC_LINE_OK);
        CHECK_INT(parse("").kind, GC_LINE_EMPTY);
        l = parse("error:9");
        CHECK(l.kind == GC_LINE_ERROR && l.code == 9);
        l = parse("error: Alarm lock");
        CHECK(l.kind == GC_LINE_ERROR && l.code == 0);
        CHECK_STR(l.text, "Alarm lock");
        l = parse("ALARM:3");
        CHECK(l.kind == GC_LINE_ALARM && l.code == 3);
        l = parse("ALARM: Abort during cycle");
        CHECK(l.kind == GC_LINE_ALARM && l.code == 0);
        l = parse("Grbl 1.1h ['$' for help]");
        CHECK(l.kind == GC_LINE_GREETING && l.flavor == GC_FLAVOR_GRBL);
        l = parse("Horus 0.2 ['$' for help]");
        CHECK(l.kind == GC_LINE_GREETING && l.flavor == GC_FLAVOR_HORUS);
        CHECK_INT(parse("Marlin 2.0 ['$' for help]").kind, GC_LINE_OTHER);
        l = parse("[MSG:'$H'|'$X' to unlock]");
        CHECK(l.kind == GC_LINE_MSG && l.alarm_lock && !l.unlocked);
        l = parse("['$H'|'$X' to unlock]");
        CHECK(l.kind == GC_LINE_MSG && l.alarm_lock);
        l = parse("[Caution: Unlocked]");
        CHECK(l.kind == GC_LINE_MSG && l.unlocked && !l.alarm_lock);
        CHECK(parse("[MSG:Caution: Unlocked]").unlocked);
        CHECK(!parse("[MSG:Pgm End]").alarm_lock);
        l = parse("780");
        CHECK(l.kind == GC_LINE_OTHER);
}

static void test_status(void)
{
        struct gc_line l;

        l = parse("<Idle|MPos:1.500,-2.000,0.000|FS:0,0|WCO:0.000,0.000,0.000>");
        CHECK(l.kind == GC_LINE_STATUS && l.status.state == GC_ST_IDLE);
        CHECK_NEAR(l.status.mpos[0], 1.5, 0);
        CHECK_NEAR(l.status.mpos[1], -2.0, 0);
        CHECK_INT(parse("<Hold:0|MPos:0.000,0.000,0.000|FS:0,0>").status.state, GC_ST_HELD);
        CHECK_INT(parse("<Hold:1|MPos:0.000,0.000,0.000|FS:0,0>").status.state, GC_ST_HOLD);
        CHECK_INT(parse("<Home|MPos:0.000,0.000,0.000|FS:0,0>").status.state, GC_ST_HOME);
        CHECK_INT(parse("<Jog|MPos:0.000,0.000,0.000|FS:0,0>").status.state, GC_ST_RUN);
        CHECK_INT(parse("<Door:1|MPos:0.000,0.000,0.000|FS:0,0>").status.state, GC_ST_OTHER);
        l = parse("<Run,MPos:90.000,0.000,0.000,WPos:90.000,0.000,0.000>");
        CHECK(l.status.state == GC_ST_RUN);
        CHECK_NEAR(l.status.mpos[0], 90.0, 0);
        CHECK_INT(parse("<Queue,MPos:0.000,0.000,0.000,WPos:0.000,0.000,0.000>").status.state,
                  GC_ST_RUN);
        CHECK_INT(parse("<Alarm,MPos:0.000,0.000,0.000,WPos:0.000,0.000,0.000>").status.state,
                  GC_ST_ALARM);
        CHECK_INT(gc_parse_line("<Idle|WPos:0.000,0.000,0.000>", &l), -EPROTO);
        CHECK_INT(gc_parse_line("<Idle|MPos:1.000,x>", &l), -EPROTO);
        CHECK_INT(gc_parse_line("<Idle|MPos:1.000,0.000,0.000", &l), -EPROTO);
}

static void test_commands(void)
{
        char buf[64];

        CHECK_INT(gc_format_move(buf, sizeof(buf), 0, 90.0, 5400.0), 16);
        CHECK_STR(buf, "G1 X90.000 F5400");
        CHECK(gc_format_move(buf, sizeof(buf), 2, -0.0, 60.0) > 0);
        CHECK_STR(buf, "G1 Z0.000 F60");
        CHECK_INT(gc_format_move(buf, sizeof(buf), 3, 1.0, 60.0), -ERANGE);
        CHECK_INT(gc_format_move(buf, sizeof(buf), 0, NAN, 60.0), -ERANGE);
        CHECK_INT(gc_format_move(buf, sizeof(buf), 0, 1.0, 0.0), -ERANGE);
        CHECK_INT(gc_format_move(buf, 8, 0, 1.0, 60.0), -ENOBUFS);
        CHECK_INT(gcsw_format(buf, sizeof(buf), 2, true), 6);
        CHECK_STR(buf, "M71 T2");
        CHECK(gcsw_format(buf, sizeof(buf), 1, false) > 0);
        CHECK_STR(buf, "M70 T1");
        CHECK_NEAR(gc_wrap(-10.0), 350.0, 1e-12);
        CHECK_NEAR(gc_wrap(720.0), 0.0, 0);
}

/* Loads text as a rig file; returns the result, the message in err. */
static int load(const char *text, struct rig_config **rc, char *err, size_t len)
{
        char path[] = "/tmp/gonio-gcode-XXXXXX";
        int fd = mkstemp(path);

        CHECK(fd >= 0);
        CHECK((size_t)write(fd, text, strlen(text)) == strlen(text));
        close(fd);
        int r = rigconf_load(path, registry_backends, rc, err, len);
        unlink(path);
        return r;
}

#define SERIAL "rig: t\nbuses:\n  - { name: s, type: serial, port: /dev/null }\n"

static void expect_error(const char *text, const char *want)
{
        struct rig_config *rc = NULL;
        char err[512] = "";

        CHECK_INT(load(text, &rc, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, want);
}

static void test_maps(void)
{
        struct rig_config *rc = NULL;
        char err[512] = "";

        CHECK_INT(load(SERIAL "axes:\n  - { name: a, gcode: { bus: s, flavor: grbl, axis: Z,"
                              " steps_per_deg: 40 } }\n"
                              "  - { name: b, gcode: { bus: s } }\n"
                              "laser: { name: l, gcode-laser: { bus: s, tool: 2 } }\n",
                       &rc, err, sizeof(err)),
                  0);
        const struct gcax_conf *a = rc->axes[0].backend.conf, *b = rc->axes[1].backend.conf;
        CHECK(a->flavor == GC_FLAVOR_GRBL && a->axis == 2 && a->steps_per_deg == 40);
        CHECK(b->flavor == GC_FLAVOR_HORUS && b->axis == 0);
        CHECK_NEAR(b->steps_per_deg, 16.0 / 1.8, 1e-12);
        CHECK_INT(((const struct gcsw_conf *)rc->lasers[0].backend.conf)->tool, 2);
        rigconf_free(rc);
        expect_error(SERIAL "axes:\n  - { name: a, gcode: { bus: s, flavor: marlin } }\n",
                     ":5: key 'flavor': 'marlin' is no G-code flavor (horus, grbl)");
        expect_error(SERIAL "axes:\n  - { name: a, gcode: { bus: s, axis: A } }\n",
                     ":5: key 'axis': 'A' is not X, Y or Z");
        expect_error(SERIAL "axes:\n  - { name: a, gcode: { bus: s } }\n"
                            "  - { name: b, gcode: { bus: s, axis: X } }\n",
                     "axis");
        expect_error(SERIAL "laser: { name: l, gcode-laser: { bus: s, tool: 5 } }\n", "tool");
        expect_error("rig: t\nbuses:\n  - { name: m, type: modbus-rtu, port: /dev/null }\n"
                     "axes:\n  - { name: a, gcode: { bus: m } }\n",
                     "bus");
}

int main(void)
{
        test_lines();
        test_status();
        test_commands();
        test_maps();
        return 0;
}
