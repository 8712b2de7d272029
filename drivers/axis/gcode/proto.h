/* proto.h - serial G-code controllers (docs/gcode.md): the Horus/Ciclop firmware (derived
 * from GRBL 0.9) and GRBL 1.1. Pure encoding and decoding of their lines, no I/O: the reply
 * lines a controller sends (ok, error, alarm, status reports, greeting, messages) and the
 * command lines the "gcode" axis backend writes. gonio-sim's emulator (sim/gcode_emu.c)
 * shares the constants and the backend map, never the parser. */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include "common/rigconf.h"
#include "drivers/axis/axis.h"

/* Realtime commands: single bytes acted on as they arrive, without a newline. */
#define GC_RT_RESET  0x18 /* Ctrl-X: soft reset, answered by the greeting line */
#define GC_RT_STATUS '?'
#define GC_RT_HOLD   '!'
#define GC_RT_RESUME '~'

/* Axes a controller reports (MPos:x,y,z). */
#define GC_N_AXES 3
/* Longest line either side sends (both firmwares: 80 characters of line buffer). */
#define GC_LINE_MAX 128
/* Steps per degree of the Horus firmware's default X axis: 1/16 microsteps of a 1.8 deg
 * motor (its $100 default). */
#define GC_STEPS_PER_DEG_DEFAULT (16.0 / 1.8)

enum gc_flavor {
        GC_FLAVOR_HORUS, /* bq Horus/Ciclop board: "Horus 0.2", GRBL 0.9 replies */
        GC_FLAVOR_GRBL,  /* GRBL 1.1: "Grbl 1.1h", numeric errors, '|' status fields */
};

/* What the axis backend reads from "gcode: { bus: ciclop, flavor: horus, axis: X,
 * steps_per_deg: 8.889 }". */
struct gcax_conf {
        enum gc_flavor flavor; /* horus when not given */
        int axis;              /* 0 for X (default), 1 Y, 2 Z */
        double steps_per_deg;  /* the controller's $100..$102; the emulator counts steps */
};

enum gc_line_kind {
        GC_LINE_EMPTY,    /* the blank line before a greeting */
        GC_LINE_OK,       /* "ok" */
        GC_LINE_ERROR,    /* "error:N" (GRBL 1.1) or "error: Text" (Horus) */
        GC_LINE_ALARM,    /* "ALARM:N" or "ALARM: Text" */
        GC_LINE_STATUS,   /* "<...>" */
        GC_LINE_GREETING, /* "Grbl 1.1h ['$' for help]", "Horus 0.2 ['$' for help]" */
        GC_LINE_MSG,      /* "[MSG:...]" or "[...]" */
        GC_LINE_OTHER,    /* anything else, e.g. the value M50 prints */
};

/* Machine states of a status report. */
enum gc_state {
        GC_ST_IDLE,
        GC_ST_RUN,   /* also Queue (0.9) and Jog (1.1): motion planned or running */
        GC_ST_HOLD,  /* feed hold, still decelerating (1.1 "Hold:1", 0.9 "Hold") */
        GC_ST_HELD,  /* feed hold complete (1.1 "Hold:0") */
        GC_ST_HOME,  /* homing cycle */
        GC_ST_ALARM, /* locked: only $ commands and realtime bytes are accepted */
        GC_ST_OTHER, /* Check, Door, Sleep */
};

struct gc_status {
        enum gc_state state;
        double mpos[GC_N_AXES]; /* machine position, controller units (degrees here) */
};

/* One reply line, parsed. */
struct gc_line {
        enum gc_line_kind kind;
        int code;         /* error or alarm number (GRBL 1.1), 0 for text (Horus) */
        const char *text; /* error/alarm text or message, into the parsed line; "" */
        bool alarm_lock;  /* a message saying the controller is locked ('$H'|'$X') */
        bool unlocked;    /* a message saying $X unlocked it ("Caution: Unlocked") */
        struct gc_status status;
        enum gc_flavor flavor; /* of a greeting */
};

/* The backend (api.c), registered in drivers/registry.c as "gcode". */
extern const struct axis_ops gcax_ops;
extern const struct rig_backend gcax_backend;

/* Parses the backend map m into conf (a struct gcax_conf) and addr (the axis letter):
 * unknown keys, a flavor other than horus/grbl, an axis other than X/Y/Z and a
 * steps_per_deg outside (0, 100000] are errors at their key's line. Returns 0 or -EINVAL
 * (message in yc). Pure. */
int gcax_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc, void *conf,
                    struct rig_addr *addr);

/* "horus" or "grbl". */
const char *gc_flavor_name(enum gc_flavor f);

/* Classifies one reply line (without its line end) into *ret; ret->text points into line.
 * Returns 0, or -EPROTO for a status report it cannot read. Pure. */
int gc_parse_line(const char *line, struct gc_line *ret);

/* Writes the move command "G1 X12.345 F5400" (axis 0..2, feed in deg/min) into buf.
 * Returns its length, -ERANGE for a non-finite or huge value, -ENOBUFS. Pure. */
int gc_format_move(char *buf, size_t len, int axis, double deg, double feed_deg_min);

/* deg modulo 360 into [0, 360). */
double gc_wrap(double deg);
