/* link.h - the session with one G-code controller on one serial line, shared by every
 * device on that line (the "gcode" axes and the "gcode-laser" switches of one board).
 *
 * DESIGN
 * - A controller answers command lines strictly in order, one "ok" or "error" each, and
 *   sends other lines (status reports, alarms, messages, the greeting) in between. The
 *   link reads every line through one handler that keeps the controller's state (alarm
 *   lock, replies still owed), so any device may read what another device's command
 *   caused.
 * - Most commands are synchronous: write the line, read until its reply. A line whose reply
 *   comes only when its motion has ended (every Horus line that moves, GRBL's $H) is
 *   asynchronous: the link counts the reply as owed and returns at once; polls read it
 *   later, so the bus worker is never blocked for a whole move. While a reply is owed, a
 *   synchronous command is refused with -EBUSY (the firmware would not read it before the
 *   move ends).
 * - The link belongs to the line: it lives in the serial transport's priv slot and is freed
 *   with the transport, so devices closed before or after their bus never touch a freed
 *   link or bus (they only drop their pointer). All calls run on the bus worker. The first use
 * after the port opens resets the controller (Ctrl-X) and waits for its greeting; any timeout or
 * unexpected reply desynchronises the session, and the next use resets again (docs/gcode.md:
 *   "Resets and position loss"). */
#pragma once

#include <stdbool.h>
#include <stddef.h>

#include "drivers/axis/gcode/proto.h"
#include "drivers/bus/bus.h"

/* How long a controller may take to print its greeting after Ctrl-X (an Arduino running
 * GRBL after a DTR reset needs about 1.5 s; a soft reset is quicker). */
#define GCLINK_GREETING_MS 2500

struct gclink {
        struct bus *bus; /* borrowed: the link dies with the bus's transport */
        enum gc_flavor flavor;
        bool synced;     /* greeting seen since the port opened, no desync since */
        bool alarm;      /* locked in alarm ('$H'|'$X' to unlock, or an ALARM line) */
        int alarm_code;  /* the last ALARM line's number (GRBL), -1 for a Horus text */
        unsigned resets; /* controller resets seen (greetings), any cause */
        int owed;        /* replies owed to asynchronous lines */
        bool owed_home;  /* the owed reply is that of $H */
        int async_error; /* 0, or -EPROTO when an asynchronous line was answered error */
        bool homed;      /* $H completed (GRBL) or G50 set the origin (Horus) */
        bool motor_on;   /* M17 sent (Horus) */
        char async_cause[GC_LINE_MAX + 32];
        char value[GC_LINE_MAX]; /* the last line of kind OTHER (the M50 reading) */
};

/* The link of bus b for a device of flavor, created on first use (owned by the bus's
 * transport: valid until bus_free()). Returns 0, -EINVAL when the bus is no serial line or
 * its controller was attached with another flavor (cause in the transport), -ENOMEM. Bus
 * worker. */
int gclink_attach(struct bus *b, enum gc_flavor flavor, struct gclink **ret);

/* Opens the port if needed and, unless synced, resets the controller and waits for its
 * greeting, then reads its state. Returns 0 or -errno (cause in the transport). */
int gclink_sync(struct gclink *l);

/* Writes one command line and reads until its reply. Returns 0, -EPROTO for an error or
 * alarm reply (cause "error: Text"/"error:N"), -EBUSY while an asynchronous reply is owed,
 * -ETIMEDOUT, -errno; the cause is in the transport. */
int gclink_command(struct gclink *l, const char *line);

/* Writes one command line whose reply comes when its motion ends; the reply is read by
 * later calls (async_error gets an error reply). home: the line is $H. Returns 0, -EBUSY
 * while another reply is owed, -errno. */
int gclink_command_async(struct gclink *l, const char *line, bool home);

/* Reads the lines that have arrived, without waiting. Returns 0 or -errno. */
int gclink_drain(struct gclink *l);

/* Asks for a status report ('?') and reads until it comes, handling the lines before it.
 * Returns 0, -ETIMEDOUT, -errno. */
int gclink_status(struct gclink *l, struct gc_status *st);

/* Writes one realtime byte ('!', '~'). Returns 0 or -errno. */
int gclink_realtime(struct gclink *l, char c);

/* Soft-resets the controller (Ctrl-X), waits for the greeting and reads the state after it
 * (alarm or idle). Owed replies are dropped. Returns 0 or -errno. */
int gclink_reset(struct gclink *l);

/* The cause of the last failure ("error: Alarm lock", "no reply to 'M17' within 200 ms"). */
const char *gclink_cause(const struct gclink *l);
