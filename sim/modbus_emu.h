/* modbus_emu.h - Modbus servers that emulate the rig's controllers: axis drives
 * (register map of docs/modbus-profile.md, with a timing model) and a relay
 * module (coils), through the real libmodbus on a pseudo-terminal (RTU) or a
 * loopback TCP port.
 *
 * DESIGN: one server thread per bus serves every unit on that bus (a multi-drop
 * RS-485 line). The emulated devices' state is read by the frame server through
 * sim_emu_snapshot(), under a mutex. Faults can be injected per unit. */
#pragma once

#include <stdbool.h>

#include "common/rigconf.h"
#include "sim/render/render.h"

struct sim_emu;

enum sim_fault {
        SIM_FAULT_NONE,
        SIM_FAULT_TIMEOUT,   /* unit stops answering */
        SIM_FAULT_CRC,       /* replies with a corrupt CRC */
        SIM_FAULT_EXCEPTION, /* replies with exception 0x04 (slave device failure) */
        SIM_FAULT_STALL,     /* the axis stalls mid-move and reports fault code 1 */
        SIM_FAULT_SHORT,     /* the axis stops a few degrees short of its target: not moving,
                              * not in position, no fault code (sim/drive.h) */
        SIM_FAULT_LATE,      /* G-code controllers: every reply comes late (sim/gcode_emu.h) */
        SIM_FAULT_ERROR,     /* G-code controllers: every command line gets an error reply */
};

/* Creates the servers for every Modbus bus of rc, and the G-code controllers of its serial
 * buses (sim/gcode_emu.h). For modbus-rtu buses a pty is
 * opened and a symlink made at the bus's port path (its directory must exist);
 * for modbus-tcp a server listens on 127.0.0.1 at the bus's tcp_port (0 = any free
 * port, see sim_emu_tcp_port). time_scale > 1 runs motion faster than real time.
 * Threads start immediately. Returns 0 or -errno. */
int sim_emu_new(const struct rig_config *rc, double time_scale, struct sim_emu **ret);

/* Stops the threads, removes the symlinks. NULL is a no-op. Returns NULL. */
struct sim_emu *sim_emu_free(struct sim_emu *e);

/* The emulated rig's state now: each Modbus axis with a role at its physical angle along
 * its motion profile (wrapped to [0, 360) when continuous), NAN for roles no axis has;
 * lamps and laser from their coils. Any thread. */
void sim_emu_snapshot(struct sim_emu *e, struct gn_pose *st);

/* The pty slave path of bus name (RTU or G-code), or NULL. Valid for the emulator's lifetime. */
const char *sim_emu_pty(struct sim_emu *e, const char *bus);

/* The TCP port of bus name (TCP), or -ENOENT. */
int sim_emu_tcp_port(struct sim_emu *e, const char *bus);

/* Unplugs the Modbus RTU line (or the G-code board, sim_gcode_unplug) bus for ms milliseconds, as a
 * USB-RS485 adapter pulled out and put back: its pty closes (a client holding it sees a hangup) and
 * its symlink goes away, then a new pty appears at the same path. Returns 0, -ENOENT for no such
 * RTU bus, -EBUSY while it is unplugged. Any thread. */
int sim_emu_unplug(struct sim_emu *e, const char *bus, int ms);

/* Injects a fault into the device at (bus, unit); SIM_FAULT_NONE clears it (a latched
 * stall stays until the drive's reset command). On a G-code bus the unit is ignored and
 * sim_gcode_inject() applies (timeout, late, error, none). Stall and short apply to the current
 * move, or the next one when the axis is at rest. Returns 0, -ENOENT for an unknown device, -EINVAL
 * for a stall or short of a device that is no axis. Any thread. */
int sim_emu_inject(struct sim_emu *e, const char *bus, int unit, enum sim_fault fault);
