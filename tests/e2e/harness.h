/* harness.h - runs gonio-sim, goniod and gonioctl as separate processes for
 * end-to-end tests, as an operator would, and talks to the daemon's socket. */
#pragma once

#include <jansson.h>
#include <stdbool.h>
#include <sys/types.h>

struct rigenv {
        char dir[256];    /* temp dir holding everything below */
        char simdir[300]; /* gonio-sim's ptys and frame socket */
        char rig[300];    /* rig file */
        char sock[300];   /* goniod's control socket */
        char data[300];   /* datasets */
        char time_scale[32];
        pid_t sim, daemon;
        char daemon_log[320]; /* goniod's stderr when set (rigenv_start_logged) */
        const char *goniod, *gonioctl, *gonio_sim;
};

/* Creates a temp dir, writes the test rig (small cameras) there and starts gonio-sim
 * with time_scale (its render log at DIR/render.log) and goniod. Exits the test on failure. */
void rigenv_start(struct rigenv *e, char **argv, double time_scale);

/* Like rigenv_start with the rig file rig_text (YAML; NULL: the default test rig). */
void rigenv_start_rig(struct rigenv *e, char **argv, double time_scale, const char *rig_text);

/* Like rigenv_start, with goniod's stderr (its log) appended to e->daemon_log, DIR/goniod.log,
 * for this start and every restart. */
void rigenv_start_logged(struct rigenv *e, char **argv, double time_scale);

/* Kills goniod with SIGKILL (as a crash would) and starts it again on the same rig,
 * socket and data. */
void rigenv_crash_daemon(struct rigenv *e);

/* Writes text to path (the test fails if it cannot). */
void write_file(const char *path, const char *text);

/* Kills gonio-sim with SIGKILL (every emulated device vanishes at once) and starts it
 * again: its drives come back unhomed at 0. */
void rigenv_crash_sim(struct rigenv *e);

/* SIGTERMs both processes, waits, and removes the temp dir. */
void rigenv_stop(struct rigenv *e);

/* Runs gonioctl --socket S --json ARGS... (NULL-terminated); *out gets the parsed stdout
 * (NULL if not JSON). Returns the exit status. */
int ctl(struct rigenv *e, json_t **out, ...) __attribute__((sentinel));

/* Like ctl but exits the test unless gonioctl succeeds; returns the parsed result. */
json_t *ctl_ok(struct rigenv *e, ...) __attribute__((sentinel));

/* Connects a raw client to the daemon's socket. Returns the fd. */
int raw_connect(struct rigenv *e);

/* Sends text as is and reads one reply line (parsed), skipping notifications; lines read
 * past it are kept for the next call on the same fd (pipelined requests). */
json_t *raw_call(int fd, const char *text);

/* Sends one request to gonio-sim's control socket (e.g. a fault injection) and checks "ok". */
void sim_request(struct rigenv *e, const char *json_line);

/* Sends one request to gonio-sim's control socket and returns its parsed reply ("ok"
 * checked). */
json_t *sim_query(struct rigenv *e, const char *json_line);

/* Polls status until field state == want (or fails the test after timeout seconds). */
json_t *wait_state(struct rigenv *e, const char *want, double timeout);

/* Space-separated methods of the notifications raw_call has skipped so far. */
const char *raw_seen(void);

/* Runs a program with args and returns its exit status, stderr into err (may be NULL). */
int run_capture(char *const argv[], char *out, size_t outlen, char *err, size_t errlen);

/* Tolerance of angles compared with what gonio-sim reports, degrees. */
#define POSE_TOL_DEG 0.01

/* Checks that every row of dataset name (under e->data) describes the frame gonio-sim
 * rendered at its exposure timestamp (the render log at DIR/render.log): camera, angles of
 * the roles in roles (bit r: the rig has an axis of role r; the others must be absent),
 * lamps and laser, at the exposure's start and end. Exits the test on a mismatch (printing
 * both poses). Returns the row count. */
int64_t check_dataset_roles(struct rigenv *e, const char *name, unsigned roles);

/* ---- sessions (issue 8) ---- */

/* A session of the test rig: s1 into dataset ds1, 4 turntable x 2 light-arm positions, 2
 * lamps, 2 cameras, a laser frame per pose, a dark per camera; nothing skipped. */
extern const char *const e2e_session_text;

/* Writes text as DIR/NAME and returns its path (in path, len bytes). */
const char *session_file(struct rigenv *e, const char *name, const char *text, char *path,
                         size_t len);

/* The capture count session.plan gives for the session file (checked > 0). */
int64_t planned_captures(struct rigenv *e, const char *file);

/* Starts the session file over a new raw connection (answered once it runs) and returns
 * that fd, which receives the session's notifications. Exits the test on an error. */
int session_start_raw(struct rigenv *e, const char *file);

/* The state of session.status (e.g. "running", "paused", "none") in buf. */
const char *session_state(struct rigenv *e, char *buf, size_t len);

/* Waits until the session state is want, up to timeout seconds; fails the test when the
 * session ends or the time is out first. */
void wait_session(struct rigenv *e, const char *want, double timeout);

/* Checks that session of dataset is done with n captures, each once, rows matching the
 * render log, and that ds_check finds nothing wrong. */
void check_complete(struct rigenv *e, const char *dataset, const char *session, int64_t n);

/* Runs the session file and kills it kills times: each after a random 0.1-1.3 s (rand()),
 * goniod when who[k] has a 'd', gonio-sim when it has an 's' (both: "ds"), then resumes it
 * with session.resume. Returns when the session has ended, resuming it whenever it pauses
 * (a kill at its end), for up to 60 s. */
void session_run_killing(struct rigenv *e, const char *file, const char *const who[], int kills);
