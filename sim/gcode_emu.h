/* gcode_emu.h - emulated serial G-code controllers of gonio-sim: the Horus/Ciclop board
 * (firmware Horus 0.2, derived from GRBL 0.9) and GRBL 1.1, each on a pseudo-terminal,
 * answering the command set of docs/gcode.md as the firmware does, with the motion timing
 * of the Modbus drives (sim/drive.c).
 *
 * DESIGN: one thread per serial bus whose devices use the "gcode" axis or "gcode-laser"
 * switch backends: it reads bytes from the pty, acts on realtime bytes (?, !, ~, Ctrl-X)
 * as they arrive, and executes lines in order when the firmware would (a Horus board reads
 * no line while a move runs). State is guarded by a mutex per bus, read by
 * sim_gcode_snapshot() for the renderer. The flavor comes from the bus's devices' backend
 * maps (a bus of lasers only is a Horus board). */
#pragma once

#include "common/rigconf.h"
#include "sim/modbus_emu.h"
#include "sim/render/render.h"

/* How long each reply waits under SIM_FAULT_LATE (real time, milliseconds). */
#define SIM_GCODE_LATE_MS 600

struct sim_gcode;

/* Creates a controller for every G-code bus of rc (none: *ret is still created, with no
 * thread), with a pty and a symlink at the bus's port; the firmware greets at power-up.
 * time_scale > 1 runs motion faster than real time. Returns 0 or -errno (logged): a bus
 * whose devices disagree on the flavor is -EINVAL. */
int sim_gcode_new(const struct rig_config *rc, double time_scale, struct sim_gcode **ret);

/* Stops the threads, closes the ptys. NULL is a no-op. Returns NULL. */
struct sim_gcode *sim_gcode_free(struct sim_gcode *g);

/* Adds the G-code devices' state to st: each axis with a role at its physical angle,
 * lamps and the laser switched by M71/M70. Other entries of st are left alone. Any
 * thread. */
void sim_gcode_snapshot(struct sim_gcode *g, struct gn_pose *st);

/* The pty slave of G-code bus name, or NULL. Valid for the emulator's lifetime. */
const char *sim_gcode_pty(struct sim_gcode *g, const char *bus);

/* Injects fault into the controller of bus: SIM_FAULT_TIMEOUT (reads and ignores every
 * byte), SIM_FAULT_LATE (each reply SIM_GCODE_LATE_MS late), SIM_FAULT_ERROR (every command
 * line answered with the firmware's "unsupported command" error), SIM_FAULT_NONE clears.
 * Returns 0, -ENOENT for no G-code bus of that name, -EINVAL for another fault (open-loop
 * steppers cannot stall for the controller). Any thread. */
int sim_gcode_inject(struct sim_gcode *g, const char *bus, enum sim_fault fault);

/* Unplugs the board on bus for ms milliseconds: its pty and symlink go, the board powers
 * down (drives stop, position counter restarts at 0 where they are, lasers off, GRBL in
 * alarm), then a new pty appears and the board greets. 0, -ENOENT, -EBUSY (unplugged). */
int sim_gcode_unplug(struct sim_gcode *g, const char *bus, int ms);
