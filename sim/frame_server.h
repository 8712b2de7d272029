/* frame_server.h - gonio-sim's frame socket: renders camera frames of the simulated rig
 * on request, in the state of the emulated devices during the exposure, logs them, and
 * hands control requests (state, geometry, fault injection) to sim/control.h.
 *
 * A Unix stream socket at the port of every bus of type sim in the rig file; the
 * line-based JSON protocol is specified in docs/sim.md, section "Frame socket". */
#pragma once

#include "common/rigconf.h"
#include "sim/modbus_emu.h"
#include "sim/render/render.h"

/* Longest exposure a render request may ask for (the server sleeps that long, scaled). */
#define SIM_FS_EXPOSURE_MAX_US 100000000

/* Options of the frame server. */
struct sim_fs_options {
        double time_scale;      /* emulated seconds per real second; 0 means 1 */
        const char *render_log; /* file to append one JSON line per rendered frame, or NULL */
        const char *control;    /* path of a control socket (no "render"), or NULL */
};

/* Longest request line, newline included; longer requests are answered with an error. */
#define SIM_FS_LINE_MAX 4096

struct sim_frame_server;

/* Listens on every sim bus of rc (replacing a stale socket file; the directory must exist)
 * and serves on a thread of its own; opt may be NULL for the defaults. rc, scene and emu
 * are borrowed and must outlive the server. Returns 0, -ENOENT when the rig has no sim
 * bus, -errno when the render log cannot be opened, or -errno. */
int sim_frame_server_new(struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                         const struct sim_fs_options *opt, struct sim_frame_server **ret);

/* Stops the thread, closes the clients and removes the socket files. NULL is a no-op.
 * Returns NULL. */
struct sim_frame_server *sim_frame_server_free(struct sim_frame_server *fs);
