/* session.h - goniod's session runner: runs the plan of a session file (daemon/plan.h) on
 * the rig, shot by shot, storing every capture in the session's dataset, whose index holds
 * the plan, so that a session paused by a fault, a full disk or a crash of any process
 * resumes with every planned capture present exactly once (docs/sessions.md).
 *
 * One session at a time. While it runs it owns the rig and the open dataset: the other
 * methods that move, switch, capture or change the dataset are refused with -EBUSY. */
#pragma once

#include <jansson.h>
#include <stdbool.h>

struct manager;
struct session_runner;

/* Completion of a start or resume: result 0 (the session runs), or -errno with msg. */
typedef void (*session_done_fn)(struct manager *m, int result, const char *msg, json_t *info,
                                void *userdata);

/* Creates the runner of m (no session). Returns 0 or -ENOMEM. */
int session_runner_new(struct manager *m, struct session_runner **ret);

/* goniod is exiting: the session stops driving the rig, the capture pipeline and the index
 * (its start or resume request is answered -ECANCELED, its timers stop); the completions still
 * to come only count down. Call first in the shutdown, before anything it uses is freed. */
void session_runner_stop(struct session_runner *s);

/* Forgets the session without touching the rig or the index (goniod is exiting: the session
 * resumes from the index next time). Call after session_runner_stop, once nothing can call it
 * back (after rig_free). NULL is a no-op; returns NULL. */
struct session_runner *session_runner_free(struct session_runner *s);

/* True while a session is starting, running, pausing or paused: the rig and the open
 * dataset are its own. */
bool session_active(const struct session_runner *s);

/* Why the rig refuses other clients' operations now ("session 'x' is running"), or NULL. */
const char *session_busy_reason(const struct session_runner *s);

/* Plans the session file text (named path in messages) on this rig without moving anything.
 * Returns the plan as JSON (docs/protocol.md, session.plan) or NULL with the error (-EINVAL:
 * "FILE:LINE: key 'x': reason") in *err and msg. */
json_t *session_plan(struct session_runner *s, const char *path, const char *text, int *err,
                     char *msg, size_t len);

/* Starts the session file text: records its plan in the target dataset (created if needed),
 * then runs it. done is called once it runs or has failed to start. Returns 0, or -EBUSY
 * (a session is active), -EINVAL (the file; msg says where) without calling done. */
int session_start(struct session_runner *s, const char *path, const char *text,
                  session_done_fn done, void *userdata, char *msg, size_t len);

/* Resumes the paused session, or after a restart the unfinished session of dataset (NULL:
 * the newest unfinished one in the data directory): clears a rig fault, homes axes that lost
 * their home, and captures what the index says is missing. A session paused by a fault or a
 * full disk tries this by itself every 5 s. When a resume runs already, done gets the status
 * at once. Returns 0 (done follows) or -EBUSY/-ENOENT with msg. */
int session_resume(struct session_runner *s, const char *dataset, session_done_fn done,
                   void *userdata, char *msg, size_t len);

/* Records the unfinished session of dataset (NULL: the newest in the data directory) as
 * aborted without running it: after a restart, when nothing is loaded. Returns 0 (done
 * follows) or -EBUSY (a session is loaded: session_abort) / -EINVAL with msg. */
int session_abandon(struct session_runner *s, const char *dataset, session_done_fn done,
                    void *userdata, char *msg, size_t len);

/* Pauses at the next capture boundary (lamps and laser off). Returns 0 or -ENOENT/-EALREADY. */
int session_pause(struct session_runner *s, char *msg, size_t len);

/* Ends the session now: motion stopped, stores finished, recorded as aborted. Returns 0 or
 * -ENOENT. */
int session_abort(struct session_runner *s, char *msg, size_t len);

/* The session's state and progress (docs/protocol.md, session.status); {"state":"none"} when
 * there is none. New reference. */
json_t *session_status(const struct session_runner *s);
