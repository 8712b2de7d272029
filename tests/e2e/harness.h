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

/* Rig file rig (NULL: the default test rig) with text inserted after the first occurrence
 * of after (which it must hold), malloc'ed: a variant of a device. */
char *rig_insert(const char *rig, const char *after, const char *text);

/* Rig file rig (NULL: the default test rig) with the first occurrence of old (which it must
 * hold) replaced by text, malloc'ed. The default test rig's laser has off_on_disconnect:
 * false (one-shot `gonioctl laser on`); rig_replace(NULL, RIG_LASER_ONE_SHOT, "") gives it
 * the default. */
char *rig_replace(const char *rig, const char *old, const char *text);
#define RIG_LASER_ONE_SHOT "off_on_disconnect: false, "

/* Like rigenv_start, with goniod's stderr (its log) appended to e->daemon_log, DIR/goniod.log,
 * for this start and every restart. */
void rigenv_start_logged(struct rigenv *e, char **argv, double time_scale);

/* Like rigenv_start without goniod: the test starts it (rigenv_spawn_daemon). */
void rigenv_start_sim(struct rigenv *e, char **argv, double time_scale);

/* Like rigenv_start_sim with the rig file rig_text (YAML; NULL: the default test rig). */
void rigenv_start_sim_rig(struct rigenv *e, char **argv, double time_scale, const char *rig_text);

/* Forks goniod on e's rig and data with --socket socket, its stderr appended to DIR/goniod.log,
 * after setup(ud) ran in the child (environment, descriptors: as systemd would); sets
 * e->daemon (stopped by rigenv_stop) and does not wait for it. */
void rigenv_spawn_daemon(struct rigenv *e, const char *socket, void (*setup)(void *ud), void *ud);

/* Kills goniod with SIGKILL (as a crash would) and starts it again on the same rig,
 * socket and data. */
void rigenv_crash_daemon(struct rigenv *e);

/* SIGTERMs goniod, checks that it exits with status 0 within 10 s, and starts it again on
 * the same rig, socket and data. */
void rigenv_term_daemon(struct rigenv *e);

/* Stops goniod; then n times starts it and SIGTERMs it i * step_s after the start (while it
 * opens the devices, or earlier), checking that it ends with status 0, or by the signal when
 * that came before goniod took its signals, never by a start ended half built; then starts
 * it for good. */
void rigenv_term_starting(struct rigenv *e, int n, double step_s);

/* The monotonic clock in seconds: waits in tests have deadlines in seconds, never a count of
 * polls (a loaded machine makes each poll slower). */
double now_s(void);

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

/* A TCP connection to ip:port (IPv4, numeric; goniod's --listen-tcp or --listen-http),
 * retried for 10 s while goniod starts; the test fails after. Returns the fd. */
int tcp_connect(const char *ip, int port);

/* Makes the test certificates of script (tests/tls-certs.sh) for san ("IP:127.0.0.1") in
 * e's directory: ca.pem, server.pem, server.key, other-ca.pem. Exits 77 without openssl. */
void rigenv_make_certs(struct rigenv *e, const char *script, const char *san);

/* Moves this process into a network namespace of its own where only lo is up, with ip (an
 * IPv4 address) on it: an address beyond loopback that no other machine can reach. Call it
 * before any process starts (they all live in it). Exits 77 where none can be made (not
 * root, no ip). */
void enter_netns(const char *ip);

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

/* The angle of the axis of role (its name in gonio-sim's state: "turntable"...) as
 * gonio-sim has it, from its control socket. */
double sim_axis_deg(struct rigenv *e, const char *role);

/* Polls status until field state == want (or fails the test after timeout seconds). */
json_t *wait_state(struct rigenv *e, const char *want, double timeout);

/* Reads fd (sharing raw_call's buffer) until a notification of method whose params' state
 * is state (NULL: any); returns those params. Fails the test after timeout seconds. */
json_t *raw_wait_note(int fd, const char *method, const char *state, double timeout);

/* Space-separated methods of the notifications raw_call has skipped so far. */
const char *raw_seen(void);

/* Prints "what: <compact JSON>" to stderr (for the log of a run). */
void print_json(const char *what, json_t *j);

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

/* ---- sessions ---- */

struct ds_session_info;

/* A session of the test rig: s1 into dataset ds1, 4 turntable x 2 light-arm positions, 2
 * lamps, 2 cameras, a laser frame per pose, a dark frame and a flat field per camera; nothing
 * skipped. */
extern const char *const e2e_session_text;

/* Writes text as DIR/name into path (len bytes) and returns path. */
const char *sess_write(struct rigenv *e, const char *name, const char *text, char *path,
                       size_t len);

/* The capture count session.plan gives for file (checked > 0); its estimate_s into
 * *estimate_s unless NULL. */
int64_t sess_planned(struct rigenv *e, const char *file, double *estimate_s);

/* Sends session.run of file on a new raw connection without waiting for its answer (the
 * next raw_call on it returns it); returns that connection's fd. */
int sess_send_run(struct rigenv *e, const char *file);

/* Sends session.run of file on a new raw connection, checks that it is answered with a
 * result (the session runs) and returns that connection's fd. */
int sess_start_raw(struct rigenv *e, const char *file);

/* Writes e2e_session_text as DIR/s1.yaml, its planned capture count into *planned (unless
 * NULL), and starts it with sess_start_raw: returns that fd. */
int sess_start_default(struct rigenv *e, int64_t *planned);

/* The session's state (gonioctl session status) into buf; returns buf. */
const char *sess_state(struct rigenv *e, char *buf, size_t len);

/* Polls until the session's state is want; fails the test if it ends or after timeout s. */
void sess_wait(struct rigenv *e, const char *want, double timeout);

/* ds_check of dataset (under e->data) on a handle of its own: prints each problem and
 * returns their count. */
int sess_problems(struct rigenv *e, const char *dataset);

/* ds_session_get of session in dataset into info (the test fails if there is none). */
void sess_info(struct rigenv *e, const char *dataset, const char *session,
               struct ds_session_info *info);

/* The session is done with n captures, each once, every row matching what gonio-sim
 * rendered (all roles), and ds_check finds nothing wrong. */
void sess_check_complete(struct rigenv *e, const char *dataset, const char *session, int64_t n);

/* Runs the session file and kills it kills times: each after a random 0.1-1.3 s (rand()),
 * goniod when who[k] has a 'd', gonio-sim when it has an 's' (both: "ds"), then resumes it
 * with session.resume. Returns when the session has ended, resuming it whenever it pauses
 * (a kill at its end), for up to 60 s. */
void sess_run_killing(struct rigenv *e, const char *file, const char *const who[], int kills);
