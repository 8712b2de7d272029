/* sessconf.h - the session file: a capture described in YAML (docs/sessions.md): the
 * sweep of each axis role, the cameras and lamps, exposure, gain and HDR brackets, dark
 * and flat frames, settle times, the target dataset and free-form metadata.
 *
 * A session file is checked against the rig it runs on: camera and lamp names, sweeps
 * within the soft limits of the axis of their role, exposures within the cameras' ranges.
 * Every mistake is refused with "FILE:LINE: key 'x': reason", before anything moves. The
 * parsed struct is plain data; the planner (daemon/plan.h) expands it into shots. */
#pragma once

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "pose.h"
#include "rigconf.h"

#define SESS_MAX_BRACKETS 8
/* Most angles one sweep may list or generate. */
#define SESS_MAX_ANGLES 3600
/* Most frames of one kind (darks, flats) per exposure. */
#define SESS_MAX_FRAMES 1000
/* Brackets are within this many EV of the exposure. */
#define SESS_MAX_EV 10

/* The angles of one role, in degrees, in the order the file gives them; continuous axes'
 * angles normalised to [0, 360), no angle twice. */
struct sess_sweep {
        size_t n; /* 0: this role is not swept (its axis stays where it is) */
        double *deg;
};

struct session_conf {
        char path[RIG_PATH_MAX]; /* as given, for messages */
        char name[64];           /* session name; default: the file's basename without .yaml */
        char dataset[64];        /* target dataset name (required) */
        struct sess_sweep sweep[GN_ROLE_COUNT]; /* by role; lists or {from,to,step} in the file */
        uint32_t cameras;                       /* bit i: rig camera i (default: all) */
        uint32_t lamps;    /* bit i: rig lamp i; lit one at a time (default: all) */
        int exposure_us;   /* 0: each camera's default */
        double gain;       /* 0: each camera's default */
        size_t n_brackets; /* >= 1 */
        double bracket_ev[SESS_MAX_BRACKETS]; /* exposure x 2^ev; default 1 bracket of 0 */
        /* the laser frames (lamps off) per pose: shot i lights the lasers of bit set
         * laser_shots[i] together (key `laser`: true, a name, a list, `each`) */
        uint32_t laser_shots[RIG_MAX_LASERS];
        size_t n_laser_shots;
        bool unlit;          /* also a frame with lamps and lasers off per pose, next to the laser
                              * frames: their reference (laser minus unlit: no room light) */
        int dark_frames;     /* dark frames per (camera, exposure, gain) at the start; 0 none */
        int dark_max_age_s;  /* dark library: reuse darks younger than this (default 86400) */
        int flat_frames;     /* flat-field frames per camera at the start; 0 none */
        uint32_t flat_lamps; /* lamps lit for flats (default: the session's lamps, else all) */
        int settle_ms[GN_ROLE_COUNT];   /* extra settle after a move of that role */
        bool skip_occluded, skip_glare; /* default true */
        double occlusion_deg; /* > 0: overrides every camera's occlusion_deg of the rig file */
        char *metadata_json;  /* free-form `metadata:` map as JSON text ("{}" if none) */
        char *text;           /* the file's bytes */
};

/* Parses a session file given as text against the rig rc; path names it in messages and
 * gives the default name. The result keeps no pointer into rc or text. Returns 0 and *ret
 * (free with sessconf_free()), -EINVAL with "FILE:LINE: key 'x': reason" in err (also for
 * NULL arguments, without a message), or -ENOMEM. */
int sessconf_load_string(const char *path, const char *text, const struct rig_config *rc,
                         struct session_conf **ret, char *err, size_t errlen);

/* Reads the file at path and parses it like sessconf_load_string(). A file that cannot be
 * read gives its -errno and "PATH: reason" in err. */
int sessconf_load(const char *path, const struct rig_config *rc, struct session_conf **ret,
                  char *err, size_t errlen);

/* Frees a session config; NULL is a no-op. Returns NULL. */
struct session_conf *sessconf_free(struct session_conf *sc);

/* The exposure in µs of camera c for a base exposure exposure_us (0: the camera's default)
 * at ev: base x 2^ev, rounded to the µs. */
int sessconf_exposure_us(const struct rig_camera_conf *c, int exposure_us, double ev);
