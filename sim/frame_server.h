/* frame_server.h - gonio-sim's frame socket: renders camera frames of the simulated rig
 * on request, in the state of the emulated devices, and takes fault injections.
 *
 * A Unix stream socket at the port of every bus of type sim in the rig file; the
 * line-based JSON protocol is specified in docs/sim.md, section "Frame socket". */
#pragma once

#include "common/rigconf.h"
#include "sim/modbus_emu.h"
#include "sim/render/render.h"

/* Longest request line, newline included; longer requests are answered with an error. */
#define SIM_FS_LINE_MAX 4096

struct sim_frame_server;

/* Listens on every sim bus of rc (replacing a stale socket file; the directory must exist)
 * and serves on a thread of its own. rc, scene and emu are borrowed and must outlive the
 * server. Returns 0, -ENOENT when the rig has no sim bus, or -errno. */
int sim_frame_server_new(struct rig_config *rc, struct sim_scene *scene, struct sim_emu *emu,
                         struct sim_frame_server **ret);

/* Stops the thread, closes the clients and removes the socket files. NULL is a no-op.
 * Returns NULL. */
struct sim_frame_server *sim_frame_server_free(struct sim_frame_server *fs);
