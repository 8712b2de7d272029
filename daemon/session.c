/* session.c - goniod's session runner (see session.h, docs/sessions.md).
 *
 * DESIGN
 * The plan lives in the dataset's index. Starting a session records the whole plan there
 * (ds_session_begin) and then, like every resume, runs what the index says is missing
 * (ds_plan_pending): one code path, so a run after a crash is the run every test makes.
 * Rows carry their plan item's seq and the index refuses a second row of one seq, so a
 * capture is present at most once whatever happens; resuming makes it present at least once.
 *
 * Index work (open, begin, pending, state records, .lp files) runs on the dataset worker,
 * and only while no capture is in flight, so the storage pool's writer and the worker never
 * use the dataset at once. Everything else runs on the loop, as a state machine woken by
 * each completion (step()):
 *   LOADING    the dataset job runs
 *   PREPARING  a rig fault is cleared and the axes that lost their home are homed
 *   RUNNING    for each shot: move and switch into its pose, expose, hand the frames to the
 *              pool; the next pose's motion starts as soon as the frames are back, while the
 *              pool encodes and stores them (the pool's bounded queue holds the runner back)
 *   PAUSING    after a pause request or a failure: wait for the stores, lamps and laser off,
 *              record "paused" with the cause
 *   ENDING     after the last shot or an abort: wait for the stores, record the end, write
 *              the .lp files, close the dataset (dataset.json is rewritten) */
#include <dirent.h>
#include <errno.h>
#include <inttypes.h>
#include <stdarg.h>
#include <math.h>
#include <string.h>
#include <sys/statvfs.h>
#include <systemd/sd-event.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "common/riggeom.h"
#include "common/sessconf.h"
#include "dataset/ds_session.h"
#include "datasets.h"
#include "manager.h"
#include "plan.h"
#include "protocol/proto.h"
#include "session.h"

#define MAX_DARKS      64
#define PROGRESS_USEC  100000 /* session.progress at most 10 times a second */
#define SKIPS_LISTED   200
#define POSE_TOLERANCE 1e-4             /* deg: an axis this close to its target is not moved */
#define RETRY_USEC     (5 * 1000000ULL) /* a session paused by a fault tries again this often */
#define SPACE_MARGIN   4 /* a full disk must have room for this many uncompressed shots */
#define ABANDONED      "aborted by a client while not loaded (goniod had restarted)"
#define KIND_NAME(k)   ((const char *const[]){"image", "dark", "flat", "laser"}[k])

enum sstate { S_NONE, S_LOADING, S_PREPARING, S_RUNNING, S_PAUSING, S_PAUSED, S_ENDING };

static const char *const state_names[] = {"none",    "starting", "preparing", "running",
                                          "pausing", "paused",   "ending"};

/* One exposure still to take: the pending plan items of one shot. */
struct run_shot {
        struct gn_pose pose;
        char kind[8];
        int bracket, exposure_us;
        double gain;
        size_t n;
        int cams[RIG_MAX_CAMERAS];
        int64_t seq[RIG_MAX_CAMERAS];
};

/* The dark frame to subtract from captures of one camera, exposure and gain. */
struct dark {
        int cam, exposure_us;
        double gain;
        int64_t id;
};

struct session_runner {
        struct manager *m;
        enum sstate state;
        char name[DS_NAME_MAX], dataset[DS_NAME_MAX];
        char reason[256];
        int settle_ms[GN_ROLE_COUNT];
        struct run_shot *shots;
        size_t n_shots, next;
        bool positioned;       /* the rig is in shots[next]'s pose and lighting */
        unsigned ops;          /* rig operations in flight (moves, switches, homing, settle) */
        bool exposing;         /* a take's frames are not back yet */
        unsigned takes;        /* takes whose stores have not all answered */
        unsigned ref_takes;    /* of which darks and flats, whose row ids later shots record */
        int pos_phase;         /* of position(): 0 to start, 1 moving and switching, 2 settling */
        int settle_pending_ms; /* extra settle after the moves in flight */
        int error;             /* first failure of this run: pauses it */
        bool pause_req, abort_req;
        bool lights_off; /* pausing or ending: lamps and laser were switched off */
        int64_t planned, captured, captured_run;
        uint64_t t_run_ns, t_progress_ns;
        double estimate_s; /* timing model of what remained when the run began */
        struct dark darks[MAX_DARKS];
        size_t n_darks;
        int64_t flats[RIG_MAX_CAMERAS]; /* the newest flat field's row per camera, 0: none */
        sd_event_source *settle_timer;
        sd_event_source *retry_timer; /* paused by a fault or a full disk: resume when it is gone */
        char busy[160];               /* session_busy_reason() */
        char ended[16]; /* how the last session ended: "done", "aborted" ("" while one runs) */
        session_done_fn done; /* the start or resume request, answered once running */
        void *done_ud;
};

static void step(struct session_runner *s);

/* ---- small helpers ---- */

static const struct rig_config *rc_of(const struct session_runner *s)
{
        return s->m->rc;
}

static void set_error(struct session_runner *s, int err, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));
static void set_error(struct session_runner *s, int err, const char *fmt, ...)
{
        va_list ap;

        if (s->error < 0)
                return;
        s->error = err;
        va_start(ap, fmt);
        vsnprintf(s->reason, sizeof(s->reason), fmt, ap);
        va_end(ap);
}

static bool drained(const struct session_runner *s)
{
        return s->ops == 0 && !s->exposing && s->takes == 0;
}

static void notify_state(struct session_runner *s)
{
        manager_notify_json(s->m, "session.state", session_status(s));
}

static void set_state(struct session_runner *s, enum sstate st)
{
        s->state = st;
        snprintf(s->busy, sizeof(s->busy), "session '%s' is %s (gonioctl session %s)", s->name,
                 state_names[st], st == S_PAUSED ? "abort" : "pause or abort");
        notify_state(s);
}

/* Answers the start or resume request, once. */
static void answer(struct session_runner *s, int result, const char *msg)
{
        session_done_fn done = s->done;

        s->done = NULL;
        if (done)
                done(s->m, result, msg, session_status(s), s->done_ud);
}

static int64_t dark_of(const struct session_runner *s, int cam, int exposure_us, double gain)
{
        for (size_t i = 0; i < s->n_darks; i++)
                if (s->darks[i].cam == cam && s->darks[i].exposure_us == exposure_us &&
                    s->darks[i].gain == gain)
                        return s->darks[i].id;
        return 0;
}

static void remember_dark(struct session_runner *s, int cam, int exposure_us, double gain,
                          int64_t id)
{
        size_t i;

        for (i = 0; i < s->n_darks; i++)
                if (s->darks[i].cam == cam && s->darks[i].exposure_us == exposure_us &&
                    s->darks[i].gain == gain)
                        break;
        if (i == MAX_DARKS)
                return;
        s->darks[i] = (struct dark){cam, exposure_us, gain, id};
        s->n_darks += i == s->n_darks;
}

/* ---- status ---- */

json_t *session_status(const struct session_runner *s)
{
        double elapsed = s->t_run_ns ? (gn_monotonic_ns() - s->t_run_ns) / 1e9 : 0;
        double rate = elapsed > 0 ? s->captured_run / elapsed : 0;
        int64_t remaining = s->planned - s->captured;
        double eta = rate > 0 ? remaining / rate : s->estimate_s;

        json_t *st;

        if (s->state == S_NONE && !s->ended[0])
                return json_pack("{ss}", "state", "none");
        st = json_pack("{sssssssssIsIsIsfsfsfsIsI}", "state", state_names[s->state], "name",
                       s->name, "dataset", s->dataset, "reason", s->reason, "planned",
                       (json_int_t)s->planned, "captured", (json_int_t)s->captured, "remaining",
                       (json_int_t)remaining, "rate_per_s", rate, "eta_s", eta, "elapsed_s",
                       elapsed, "shot", (json_int_t)s->next, "shots", (json_int_t)s->n_shots);
        if (st && s->state == S_NONE)
                json_object_set_new(st, "ended", json_string(s->ended));
        if (st && s->error < 0)
                json_object_set_new(st, "code", json_integer(proto_errno_to_code(s->error)));
        return st;
}

static void progress(struct session_runner *s)
{
        uint64_t now = gn_monotonic_ns();

        if (now - s->t_progress_ns < PROGRESS_USEC * 1000ULL && s->captured < s->planned)
                return;
        s->t_progress_ns = now;
        manager_notify_json(s->m, "session.progress", session_status(s));
}

bool session_active(const struct session_runner *s)
{
        return s && s->state != S_NONE;
}

const char *session_busy_reason(const struct session_runner *s)
{
        return session_active(s) ? s->busy : NULL;
}

/* ---- planning ---- */

/* The plan as the protocol shows it and the index keeps it (session.plan). */
static json_t *plan_json(const struct rig_config *rc, const struct session_conf *sc,
                         const struct plan *p)
{
        json_t *order = json_array(), *skips = json_array(), *kinds = json_object();
        size_t per_kind[4] = {0};

        for (int i = 0; i < p->n_order; i++)
                json_array_append_new(order, json_string(gn_role_name(p->order[i])));
        for (size_t i = 0; i < p->n_skips && i < SKIPS_LISTED; i++)
                json_array_append_new(skips, json_string(p->skips[i].reason));
        for (size_t i = 0; i < p->n_shots; i++)
                per_kind[p->shots[i].kind] += __builtin_popcount(p->shots[i].cameras);
        for (int k = 0; k < 4; k++)
                json_object_set_new(kinds, KIND_NAME(k), json_integer(per_kind[k]));
        return json_pack("{sssssssIsIsIsfsfsososIso}", "session", sc->name, "dataset", sc->dataset,
                         "rig", rc->name, "captures", (json_int_t)p->n_captures, "shots",
                         (json_int_t)p->n_shots, "moves", (json_int_t)p->n_moves, "estimate_s",
                         p->estimate_s, "lower_bound_s", p->lower_bound_s, "order", order, "kinds",
                         kinds, "skipped_count", (json_int_t)p->n_skips, "skipped", skips);
}

/* Parses and plans text from the rig's current pose. */
static int plan_text(struct session_runner *s, const char *path, const char *text,
                     struct session_conf **sc, struct plan **p, char *msg, size_t len)
{
        struct gn_pose start = rig_pose(s->m->rig);
        int r;

        r = sessconf_load_string(path, text, rc_of(s), sc, msg, len);
        if (r < 0)
                return r;
        r = plan_build(rc_of(s), *sc, &start, p);
        if (r < 0) {
                snprintf(msg, len, "%s: cannot plan: %s", path, strerror(-r));
                *sc = sessconf_free(*sc);
        }
        return r;
}

json_t *session_plan(struct session_runner *s, const char *path, const char *text, int *err,
                     char *msg, size_t len)
{
        struct session_conf *sc = NULL;
        struct plan *p = NULL;
        json_t *out;

        *err = plan_text(s, path, text, &sc, &p, msg, len);
        if (*err < 0)
                return NULL;
        out = plan_json(rc_of(s), sc, p);
        plan_free(p);
        sessconf_free(sc);
        return out;
}

/* The plan's captures as index items: one per camera of each shot. */
static struct ds_plan_item *plan_items(const struct rig_config *rc, const struct plan *p, size_t *n)
{
        struct ds_plan_item *items = calloc(p->n_captures ? p->n_captures : 1, sizeof(*items));
        size_t k = 0;

        if (!items)
                return NULL;
        for (size_t i = 0; i < p->n_shots; i++) {
                const struct plan_shot *sh = &p->shots[i];
                int64_t seq = sh->seq;
                for (size_t c = 0; c < rc->n_cameras && k < p->n_captures; c++) {
                        if (!(sh->cameras & (1u << c)))
                                continue;
                        items[k] = (struct ds_plan_item){.seq = seq++,
                                                         .shot = i + 1,
                                                         .bracket = sh->bracket,
                                                         .pose = sh->pose,
                                                         .exposure_us =
                                                                 plan_shot_exposure_us(rc, sh, c),
                                                         .gain = plan_shot_gain(rc, sh, c)};
                        snprintf(items[k].camera, sizeof(items[k].camera), "%s",
                                 rc->cameras[c].name);
                        snprintf(items[k].kind, sizeof(items[k].kind), "%s", KIND_NAME(sh->kind));
                        k++;
                }
        }
        *n = k;
        return items;
}

/* ---- loading: the dataset job ---- */

/* What a start or resume hands to the dataset worker and gets back. */
struct load_job {
        struct session_runner *s;
        bool begin;      /* start: record the session and its plan */
        bool from_pause; /* resume of the paused session: paused again on failure */
        bool abandon;    /* record the session as aborted instead of loading it */
        char data_dir[PATH_MAX];
        char dataset[DS_NAME_MAX]; /* "" (resume): the newest unfinished session's */
        char name[DS_NAME_MAX];    /* "" (resume): the dataset's unfinished session */
        struct ds *old;            /* the dataset that was open (maybe the target) */
        char old_name[DS_NAME_MAX];
        int64_t old_count;
        struct ds *d; /* the target, open */
        int64_t count;
        struct ds_plan_item *items; /* begin: the plan */
        size_t n_items;
        char *file_text, *plan_json, *meta_json;
        int dark_max_age_s;
        struct ds_plan_item *pending; /* what the index says is missing */
        size_t n_pending, cap;
        struct ds_session_info info;
        struct dark darks[MAX_DARKS];
        size_t n_darks;
        int64_t flats[RIG_MAX_CAMERAS];
        char msg[300];
};

static void load_job_free(struct load_job *j)
{
        free(j->items);
        free(j->file_text);
        free(j->plan_json);
        free(j->meta_json);
        free(j->pending);
        ds_session_info_clear(&j->info);
        free(j);
}

static int collect_pending(const struct ds_plan_item *it, void *userdata)
{
        struct load_job *j = userdata;

        if (j->n_pending == j->cap) {
                size_t cap = j->cap ? 2 * j->cap : 256;
                void *p = realloc(j->pending, cap * sizeof(*j->pending));
                if (!p)
                        return -ENOMEM;
                j->pending = p;
                j->cap = cap;
        }
        j->pending[j->n_pending++] = *it;
        return 0;
}

static int camera_index(const struct rig_config *rc, const char *name)
{
        for (size_t i = 0; i < rc->n_cameras; i++)
                if (strcmp(rc->cameras[i].name, name) == 0)
                        return i;
        return -ENOENT;
}

/* The library's dark frame for each camera, exposure and gain still to be captured. */
static void find_darks(struct load_job *j, const struct rig_config *rc)
{
        for (size_t i = 0; i < j->n_pending && j->n_darks < MAX_DARKS; i++) {
                const struct ds_plan_item *it = &j->pending[i];
                int cam = camera_index(rc, it->camera);
                int64_t id;
                bool known = false;

                for (size_t k = 0; k < j->n_darks; k++)
                        known |= j->darks[k].cam == cam &&
                                 j->darks[k].exposure_us == it->exposure_us &&
                                 j->darks[k].gain == it->gain;
                if (cam < 0 || known || strcmp(it->kind, "dark") == 0)
                        continue;
                id = ds_find_dark(j->d, it->camera, it->exposure_us, it->gain, 0);
                if (id > 0)
                        j->darks[j->n_darks++] = (struct dark){cam, it->exposure_us, it->gain, id};
        }
}

/* Brings the library's dark frame for it (younger than not_before) into d, outside the plan:
 * its row id, 0 when the library has none, or -errno. */
static int64_t import_dark(struct ds *d, struct ds *lib, const struct ds_plan_item *it,
                           uint64_t not_before)
{
        struct ds_capture label = {.session = DS_LIBRARY_SESSION, .kind = "dark"};
        int64_t id = lib ? ds_find_dark(lib, it->camera, it->exposure_us, it->gain, not_before) : 0;

        return id > 0 ? ds_import_frame(d, lib, id, &label) : id;
}

/* Drops the planned dark frames that the dataset, or the data directory's dark library
 * (imported from there), already holds younger than the session's limit. */
static void reuse_darks(struct load_job *j)
{
        uint64_t now = gn_realtime_ns(), age = (uint64_t)j->dark_max_age_s * 1000000000ULL;
        uint64_t not_before = now > age ? now - age : 0;
        struct ds *lib = NULL;
        size_t k = 0;

        if (ds_library_open(j->data_dir, false, &lib) < 0)
                lib = NULL;
        for (size_t i = 0; i < j->n_items; i++) {
                const struct ds_plan_item *it = &j->items[i];
                if (strcmp(it->kind, "dark") == 0 && it->seq > 0 &&
                    (ds_find_dark(j->d, it->camera, it->exposure_us, it->gain, not_before) > 0 ||
                     import_dark(j->d, lib, it, not_before) > 0))
                        continue;
                j->items[k++] = *it;
        }
        j->n_items = k;
        ds_close(lib);
}

/* Opens dataset name in dir (creating it when create), or -ENOENT. */
static int open_dataset(const char *dir, const char *name, bool create, const char *rig_text,
                        struct ds **ret)
{
        char path[PATH_MAX];

        if ((size_t)snprintf(path, sizeof(path), "%s/%s", dir, name) >= sizeof(path))
                return -ENAMETOOLONG;
        if (create && access(path, F_OK) < 0 && errno == ENOENT)
                return ds_create(path, name, rig_text, ret);
        return ds_open(path, ret);
}

DEFINE_TRIVIAL_CLEANUP_FUNC(DIR *, closedir);

/* Finds the dataset of the newest unfinished session in the data directory. */
static int find_unfinished(struct load_job *j)
{
        _cleanup_(closedirp) DIR *dir = opendir(j->data_dir);
        char best[32] = "";
        struct dirent *de;

        if (!dir)
                return -errno;
        while ((de = readdir(dir))) {
                struct ds_session_info info = {0};
                char name[DS_NAME_MAX];
                struct ds *d = NULL;

                if (de->d_name[0] == '.' || strlen(de->d_name) >= DS_NAME_MAX ||
                    open_dataset(j->data_dir, de->d_name, false, NULL, &d) < 0)
                        continue;
                if (ds_session_unfinished(d, name, sizeof(name)) == 0 &&
                    ds_session_get(d, name, &info) == 0 && strcmp(info.started, best) > 0) {
                        snprintf(best, sizeof(best), "%s", info.started);
                        snprintf(j->dataset, sizeof(j->dataset), "%s", de->d_name);
                }
                ds_session_info_clear(&info);
                ds_close(d);
        }
        return j->dataset[0] ? 0 : -ENOENT;
}

/* Records why a job failed (the first reason only) and returns r. */
static int job_fail(struct load_job *j, int r, const char *fmt, ...)
        __attribute__((format(printf, 3, 4)));
static int job_fail(struct load_job *j, int r, const char *fmt, ...)
{
        va_list ap;

        if (!j->msg[0]) {
                va_start(ap, fmt);
                vsnprintf(j->msg, sizeof(j->msg), fmt, ap);
                va_end(ap);
        }
        return r;
}

/* Records the new session and its plan, or finds the session to resume. */
static int begin_or_find(struct load_job *j, const char *rig_text)
{
        int r;

        if (j->begin) {
                reuse_darks(j);
                r = ds_session_begin(j->d, j->name, j->file_text, rig_text, j->plan_json,
                                     j->meta_json, j->items, j->n_items);
                if (r == -EEXIST)
                        return job_fail(j, -EBUSY,
                                        "dataset '%s' has a session '%s' already (gonioctl "
                                        "session resume, or name this one differently)",
                                        j->dataset, j->name);
                return r;
        }
        if (!j->name[0] && ds_session_unfinished(j->d, j->name, sizeof(j->name)) < 0) {
                snprintf(j->msg, sizeof(j->msg), "dataset '%s' has no unfinished session",
                         j->dataset);
                return -ENOENT;
        }
        return 0;
}

/* Opens the target (or takes the open dataset when it is the target). */
static int load_dataset(struct load_job *j, const char *rig_text)
{
        int r;

        if (!j->dataset[0] && (r = find_unfinished(j)) < 0)
                return job_fail(j, r, "no unfinished session in %s", j->data_dir);
        if (j->old && strcmp(j->old_name, j->dataset) == 0) {
                j->d = TAKE_PTR(j->old);
                return 0;
        }
        r = open_dataset(j->data_dir, j->dataset, j->begin, rig_text, &j->d);
        if (r < 0)
                return job_fail(j, r, "cannot open dataset '%s': %s", j->dataset,
                                r == -ENOENT ? "no such dataset" : strerror(-r));
        return 0;
}

static int load(struct load_job *j)
{
        const struct rig_config *rc = j->s->m->rc;
        int r;

        if ((r = load_dataset(j, rc->text)) < 0)
                return r;
        if (j->abandon && (r = begin_or_find(j, rc->text)) >= 0 &&
            (r = ds_session_set_state(j->d, j->name, "aborted", ABANDONED)) >= 0)
                r = ds_session_get(j->d, j->name, &j->info);
        if (j->abandon && r < 0)
                return job_fail(j, r, "dataset '%s': %s", j->dataset, strerror(-r));
        if (j->abandon) {
                j->old = ds_close(j->old);
                return 0;
        }
        if ((r = begin_or_find(j, rc->text)) < 0 ||
            (r = ds_session_get(j->d, j->name, &j->info)) < 0 ||
            (r = ds_session_set_state(j->d, j->name, "running", "")) < 0 ||
            (r = ds_plan_pending(j->d, j->name, collect_pending, j)) < 0)
                return job_fail(j, r, "dataset '%s', session '%s': %s", j->dataset, j->name,
                                ds_last_error(j->d)[0] ? ds_last_error(j->d) : strerror(-r));
        find_darks(j, rc);
        for (size_t i = 0; i < rc->n_cameras; i++)
                j->flats[i] = MAX(ds_find_flat(j->d, rc->cameras[i].name), 0);
        j->count = ds_count(j->d);
        j->old = ds_close(j->old);
        return 0;
}

static int load_job_run(void *userdata)
{
        struct load_job *j = userdata;
        int r = load(j);

        if (r < 0 && j->d && !j->old && j->old_name[0])
                j->old = TAKE_PTR(j->d); /* the open dataset goes back */
        else if (r < 0)
                j->d = ds_close(j->d);
        return r;
}

/* ---- loaded: the shots still to take ---- */

static void shot_add_item(struct run_shot *sh, const struct ds_plan_item *it, int cam)
{
        if (sh->n == 0) {
                sh->pose = it->pose;
                snprintf(sh->kind, sizeof(sh->kind), "%s", it->kind);
                sh->bracket = it->bracket;
                sh->exposure_us = it->exposure_us;
                sh->gain = it->gain;
        }
        sh->cams[sh->n] = cam;
        sh->seq[sh->n++] = it->seq;
}

/* True when it can be exposed in the same request as the items of sh so far. */
static bool same_request(const struct run_shot *sh, const struct ds_plan_item *it)
{
        return sh->n < RIG_MAX_CAMERAS && sh->exposure_us == it->exposure_us &&
               sh->gain == it->gain;
}

/* Groups the pending items (seq order) into shots. Returns 0 or -ENOMEM/-ENOENT (a camera
 * of the plan is not in this rig). */
static int build_shots(struct session_runner *s, const struct load_job *j)
{
        int64_t shot = -1;

        free(s->shots);
        s->n_shots = s->next = 0;
        if (!(s->shots = calloc(j->n_pending ? j->n_pending : 1, sizeof(*s->shots))))
                return -ENOMEM;
        for (size_t i = 0; i < j->n_pending; i++) {
                const struct ds_plan_item *it = &j->pending[i];
                int cam = camera_index(rc_of(s), it->camera);

                if (cam < 0) {
                        set_error(s, -ENOENT, "the plan names camera '%s', not in this rig",
                                  it->camera);
                        return -ENOENT;
                }
                if (it->shot != shot || !same_request(&s->shots[s->n_shots - 1], it))
                        s->n_shots++; /* cameras of other exposures or gains: one shot each */
                shot = it->shot;
                shot_add_item(&s->shots[s->n_shots - 1], it, cam);
        }
        return 0;
}

/* Re-reads the settle times of the recorded session file (the rig may have changed since;
 * then none). */
static void read_settle(struct session_runner *s, const char *text)
{
        struct session_conf *sc = NULL;
        char err[256];

        memset(s->settle_ms, 0, sizeof(s->settle_ms));
        if (!text || sessconf_load_string(s->name, text, rc_of(s), &sc, err, sizeof(err)) < 0) {
                log_warning("session '%s': the recorded session file no longer loads on this "
                            "rig (%s); no extra settle times",
                            s->name, text ? err : "none");
                return;
        }
        memcpy(s->settle_ms, sc->settle_ms, sizeof(s->settle_ms));
        sessconf_free(sc);
}

/* The timing model's duration of the shots still to take, from the rig's pose now. */
static double estimate_rest(const struct session_runner *s)
{
        struct plan_shot *ps = calloc(s->n_shots ? s->n_shots : 1, sizeof(*ps));
        struct gn_pose now = rig_pose(s->m->rig);
        double t;

        if (!ps)
                return 0;
        for (size_t i = 0; i < s->n_shots; i++) {
                const struct run_shot *sh = &s->shots[i];
                ps[i] = (struct plan_shot){.pose = sh->pose,
                                           .exposure_us = sh->exposure_us,
                                           .gain = sh->gain,
                                           .bracket = sh->bracket};
                for (size_t k = 0; k < sh->n; k++)
                        ps[i].cameras |= 1u << sh->cams[k];
        }
        t = plan_estimate(rc_of(s), ps, s->n_shots, &now);
        free(ps);
        return t;
}

static void prepare(struct session_runner *s);

static void load_done(int result, void *userdata)
{
        struct load_job *j = userdata;
        struct session_runner *s = j->s;
        struct manager *m = s->m;
        int r = result;

        m->ds_busy = false;
        if (j->old)
                (void)datasets_attach(m, TAKE_PTR(j->old), j->old_name, j->old_count);
        snprintf(s->name, sizeof(s->name), "%s", j->name);
        snprintf(s->dataset, sizeof(s->dataset), "%s", j->dataset);
        if (r >= 0 && (r = datasets_attach(m, TAKE_PTR(j->d), j->dataset, j->count)) < 0)
                snprintf(j->msg, sizeof(j->msg), "cannot start the storage pool: %s", strerror(-r));
        if (r >= 0 && (r = build_shots(s, j)) < 0)
                snprintf(j->msg, sizeof(j->msg), "%s", s->reason);
        if (r < 0) {
                s->state = j->from_pause && capture_dataset(m->capture) ? S_PAUSED : S_NONE;
                answer(s, r, r == -ECANCELED ? "goniod is shutting down" : j->msg);
                notify_state(s);
                return load_job_free(j);
        }
        s->planned = j->info.planned;
        s->captured = j->info.captured;
        if (j->abandon) {
                snprintf(s->reason, sizeof(s->reason), "%s", ABANDONED);
                snprintf(s->ended, sizeof(s->ended), "aborted");
                set_state(s, S_NONE);
                answer(s, 0, NULL);
                return load_job_free(j);
        }
        memcpy(s->darks, j->darks, sizeof(s->darks));
        memcpy(s->flats, j->flats, sizeof(s->flats));
        s->n_darks = j->n_darks;
        read_settle(s, j->info.file_text);
        load_job_free(j);
        prepare(s);
}

/* Hands j to the dataset worker with the open dataset (the pipeline is idle). */
static int push_load(struct session_runner *s, struct load_job *j, char *msg, size_t len)
{
        struct manager *m = s->m;
        int r;

        if (m->ds_busy || capture_in_flight(m->capture) > 0) {
                snprintf(msg, len, "captures or a dataset change are in progress; try again");
                return -EBUSY;
        }
        j->s = s;
        snprintf(j->data_dir, sizeof(j->data_dir), "%s", m->data_dir);
        snprintf(j->old_name, sizeof(j->old_name), "%s",
                 capture_dataset(m->capture) ? capture_dataset_name(m->capture) : "");
        j->old_count = capture_dataset_count(m->capture);
        j->old = capture_detach(m->capture);
        r = datasets_push(m, load_job_run, load_done, j);
        if (r < 0) {
                if (j->old)
                        (void)datasets_attach(m, TAKE_PTR(j->old), j->old_name, j->old_count);
                snprintf(msg, len, "the dataset worker is busy; try again");
                return r;
        }
        m->ds_busy = true;
        s->error = 0;
        s->ended[0] = 0;
        s->reason[0] = 0;
        s->pause_req = s->abort_req = false;
        set_state(s, S_LOADING);
        return 0;
}

/* ---- start and resume ---- */

/* The load job of a new session: its plan as index items and JSON. */
static struct load_job *start_job(struct session_runner *s, const struct session_conf *sc,
                                  const struct plan *p)
{
        struct load_job *j = calloc(1, sizeof(*j));
        json_t *pj = plan_json(rc_of(s), sc, p);

        if (!j || !pj || !(j->items = plan_items(rc_of(s), p, &j->n_items)) ||
            !(j->plan_json = json_dumps(pj, JSON_COMPACT)) || !(j->file_text = strdup(sc->text)) ||
            !(j->meta_json = strdup(sc->metadata_json))) {
                json_decref(pj);
                if (j)
                        load_job_free(j);
                return NULL;
        }
        json_decref(pj);
        j->begin = true;
        j->dark_max_age_s = sc->dark_max_age_s;
        snprintf(j->name, sizeof(j->name), "%s", sc->name);
        snprintf(j->dataset, sizeof(j->dataset), "%s", sc->dataset);
        return j;
}

int session_start(struct session_runner *s, const char *path, const char *text,
                  session_done_fn done, void *userdata, char *msg, size_t len)
{
        struct session_conf *sc = NULL;
        struct plan *p = NULL;
        struct load_job *j;
        char dspath[PATH_MAX];
        int r;

        if (session_active(s))
                return snprintf(msg, len, "%s", s->busy), -EBUSY;
        if ((r = plan_text(s, path, text, &sc, &p, msg, len)) < 0)
                return r;
        if (strcmp(sc->dataset, DS_LIBRARY) == 0) {
                snprintf(msg, len,
                         "%s: key 'dataset': '%s' is the dark library, not a dataset "
                         "for sessions",
                         path, sc->dataset);
                r = -EINVAL;
        } else if (datasets_path(s->m, sc->dataset, dspath, sizeof(dspath)) < 0) {
                snprintf(msg, len, "%s: key 'dataset': '%s' is not a valid dataset name", path,
                         sc->dataset);
                r = -EINVAL;
        } else if (!(j = start_job(s, sc, p))) {
                r = -ENOMEM;
        } else {
                snprintf(s->name, sizeof(s->name), "%s", sc->name);
                snprintf(s->dataset, sizeof(s->dataset), "%s", sc->dataset);
                s->done = done;
                s->done_ud = userdata;
                if ((r = push_load(s, j, msg, len)) < 0) {
                        s->done = NULL;
                        load_job_free(j);
                }
        }
        plan_free(p);
        sessconf_free(sc);
        return r;
}

/* Loads the paused session, or the unfinished session of dataset (NULL: the newest in the
 * data directory) to resume it, or with abandon to record it as aborted. */
static int load_unfinished(struct session_runner *s, const char *dataset, bool abandon,
                           session_done_fn done, void *userdata, char *msg, size_t len)
{
        struct load_job *j;
        char path[PATH_MAX];
        int r;

        if (dataset && datasets_path(s->m, dataset, path, sizeof(path)) < 0)
                return snprintf(msg, len, "'%s' is not a valid dataset name", dataset), -EINVAL;
        if (!(j = calloc(1, sizeof(*j))))
                return -ENOMEM;
        j->abandon = abandon;
        if (s->state == S_PAUSED) { /* the index says what the pause left to do */
                snprintf(j->dataset, sizeof(j->dataset), "%s", s->dataset);
                snprintf(j->name, sizeof(j->name), "%s", s->name);
                j->from_pause = true;
        } else if (dataset) {
                snprintf(j->dataset, sizeof(j->dataset), "%s", dataset);
        }
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        s->done = done;
        s->done_ud = userdata;
        if ((r = push_load(s, j, msg, len)) < 0) {
                s->done = NULL;
                load_job_free(j);
        }
        return r;
}

int session_resume(struct session_runner *s, const char *dataset, session_done_fn done,
                   void *userdata, char *msg, size_t len)
{
        if (s->state == S_LOADING || s->state == S_PREPARING || s->state == S_RUNNING) {
                if (done) /* resumed already: the caller follows it */
                        done(s->m, 0, NULL, session_status(s), userdata);
                return 0;
        }
        if (s->state != S_NONE && s->state != S_PAUSED)
                return snprintf(msg, len, "%s", s->busy), -EBUSY;
        return load_unfinished(s, dataset, false, done, userdata, msg, len);
}

int session_abandon(struct session_runner *s, const char *dataset, session_done_fn done,
                    void *userdata, char *msg, size_t len)
{
        if (s->state != S_NONE)
                return snprintf(msg, len, "%s", s->busy), -EBUSY;
        return load_unfinished(s, dataset, true, done, userdata, msg, len);
}

/* ---- preparing: fault cleared, axes homed ---- */

/* Completion of any rig operation of the runner: one less in flight; the first failure is
 * kept. */
static void on_op_done(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct session_runner *s = userdata;

        s->ops--;
        if (result < 0)
                set_error(s, result, "%s", msg ? msg : strerror(-result));
        step(s);
}

/* Homes the axes that have no home (a drive restarted, goniod restarted), swept or not, so
 * that every row records the whole pose. */
static void home_lost_axes(struct session_runner *s)
{
        struct gn_pose now = rig_pose(s->m->rig);

        for (int role = 0; role < GN_ROLE_COUNT; role++) {
                int ax = rigconf_axis_of_role(rc_of(s), role);
                int r;

                if (ax < 0 || !isnan(now.deg[role]))
                        continue;
                r = rig_home(s->m->rig, ax, on_op_done, s);
                if (r < 0)
                        set_error(s, r, "cannot home '%s': %s", rc_of(s)->axes[ax].name,
                                  r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
                else
                        s->ops++;
        }
}

static void on_fault_cleared(struct rig *rig, int result, const char *msg, void *userdata)
{
        struct session_runner *s = userdata;

        s->ops--;
        if (result < 0)
                set_error(s, result, "the rig is still in fault: %s", msg ? msg : "");
        else
                home_lost_axes(s);
        step(s);
}

/* Brings the rig to where the shots can run: fault cleared, lost homes found. */
static void prepare(struct session_runner *s)
{
        int r;

        s->positioned = false;
        s->pos_phase = 0;
        s->settle_pending_ms = 0;
        s->captured_run = 0;
        s->t_run_ns = gn_monotonic_ns();
        s->estimate_s = estimate_rest(s);
        set_state(s, S_PREPARING);
        if (strcmp(rig_state(s->m->rig), "fault") == 0) {
                r = rig_clear_fault(s->m->rig, on_fault_cleared, s);
                if (r < 0)
                        set_error(s, r, "cannot clear the rig's fault: %s", strerror(-r));
                else
                        s->ops++;
        } else {
                home_lost_axes(s);
        }
        step(s);
}

/* ---- running: position, expose ---- */

static int on_settled(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct session_runner *s = userdata;

        s->settle_timer = sd_event_source_disable_unref(s->settle_timer);
        s->ops--;
        step(s);
        return 0;
}

/* Waits the session's extra settle time of the axes just moved, as one more operation. */
static void settle(struct session_runner *s, int ms)
{
        int r = sd_event_add_time_relative(s->m->event, &s->settle_timer, CLOCK_MONOTONIC,
                                           ms * 1000ULL, 1000, on_settled, s);

        if (r < 0)
                set_error(s, r, "cannot arm the settle timer: %s", strerror(-r));
        else
                s->ops++;
}

/* Starts the moves of the axes the shot puts elsewhere; returns the longest extra settle. */
static int move_axes(struct session_runner *s, const struct run_shot *sh, const struct gn_pose *now)
{
        int settle_ms = 0;

        for (int role = 0; role < GN_ROLE_COUNT; role++) {
                int ax = rigconf_axis_of_role(rc_of(s), role);
                double target = sh->pose.deg[role];
                int r;

                if (ax < 0 || isnan(target) ||
                    (!isnan(now->deg[role]) &&
                     gn_angle_distance(now->deg[role], target) <=
                             MAX(POSE_TOLERANCE, rc_of(s)->axes[ax].deadband_deg)))
                        continue;
                r = rig_move(s->m->rig, ax, &target, false, on_op_done, s);
                if (r < 0) {
                        set_error(s, r, "move %s to %g: %s", rc_of(s)->axes[ax].name, target,
                                  r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
                        return settle_ms;
                }
                s->ops++;
                settle_ms = MAX(settle_ms, s->settle_ms[role]);
        }
        return settle_ms;
}

/* Switches lamp i (the laser: -1) to on unless it is so already. */
static void switch_to(struct session_runner *s, int i, bool on, bool is_on)
{
        int r;

        if (on == is_on)
                return;
        r = rig_switch(s->m->rig, i, on, on_op_done, s);
        if (r < 0)
                set_error(s, r, "switch %s %s: %s",
                          i < 0 ? rc_of(s)->laser.name : rc_of(s)->lamps[i].name, on ? "on" : "off",
                          r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
        else
                s->ops++;
}

/* Switches lamps and laser to the lighting of pose (all off for NULL). */
static void light(struct session_runner *s, const struct gn_pose *pose, const struct gn_pose *now)
{
        for (size_t i = 0; i < rc_of(s)->n_lamps; i++)
                switch_to(s, i, pose && (pose->lamps >> i & 1), now->lamps >> i & 1);
        if (rc_of(s)->has_laser)
                switch_to(s, -1, pose && pose->laser, now->laser);
}

/* Moves and switches the rig into the next shot's pose, then waits the session's settle time:
 * each phase ends when its operations are done (step() calls back). */
static void position(struct session_runner *s)
{
        const struct run_shot *sh = &s->shots[s->next];
        struct gn_pose now = rig_pose(s->m->rig);

        switch (s->pos_phase) {
        case 0:
                s->pos_phase = 1;
                s->settle_pending_ms = move_axes(s, sh, &now);
                light(s, &sh->pose, &now);
                if (s->ops > 0 || s->error < 0)
                        return;
                /* fallthrough */
        case 1:
                s->pos_phase = 2;
                if (s->settle_pending_ms > 0) {
                        settle(s, s->settle_pending_ms);
                        s->settle_pending_ms = 0;
                        if (s->ops > 0 || s->error < 0)
                                return;
                }
                /* fallthrough */
        default:
                s->positioned = true;
                step(s);
        }
}

/* The frames are back: the next shot may move the rig while these are stored. */
static void on_exposed(struct capture *cp, void *userdata)
{
        struct session_runner *s = userdata;

        s->exposing = false;
        s->next++;
        s->positioned = false;
        s->pos_phase = 0;
        step(s);
}

/* Every frame of a take is stored or failed. */
static void on_taken(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct session_runner *s = userdata;

        s->takes--;
        for (size_t i = 0; i < res->n_shots; i++) {
                const struct capture_shot *sh = &res->shots[i];
                if (sh->result < 0) {
                        /* the fault this failure latched may have failed a move first (-EIO,
                         * same message): the cause's errno is the store's (ENOSPC...) */
                        if (s->error < 0 && strcmp(s->reason, sh->msg) == 0)
                                s->error = sh->result;
                        set_error(s, sh->result, "%s", sh->msg);
                        continue;
                }
                s->captured++;
                s->captured_run++;
                int cam = camera_index(rc_of(s), sh->row.camera);
                if (strcmp(sh->row.kind, "dark") == 0)
                        remember_dark(s, cam, sh->row.exposure_us, sh->row.gain, sh->row.id);
                if (strcmp(sh->row.kind, "flat") == 0 && cam >= 0)
                        s->flats[cam] = sh->row.id;
        }
        progress(s);
        step(s);
}

/* A take of dark frames or flat fields is stored: the shots after it may name its rows. */
static void on_ref_taken(struct capture *cp, const struct capture_result *res, void *userdata)
{
        struct session_runner *s = userdata;

        s->ref_takes--;
        on_taken(cp, res, userdata);
}

/* Exposes the cameras of the next shot, labelled with their plan items. */
static void expose(struct session_runner *s)
{
        const struct run_shot *sh = &s->shots[s->next];
        struct capture_tag tag = {.session = s->name,
                                  .kind = sh->kind,
                                  .bracket = sh->bracket,
                                  .exposed = on_exposed,
                                  .planned = &sh->pose};
        struct cam_request req = {.exposure_us = sh->exposure_us, .gain = sh->gain};
        bool dark = strcmp(sh->kind, "dark") == 0, flat = strcmp(sh->kind, "flat") == 0;
        int r;

        for (size_t k = 0; k < sh->n; k++) {
                tag.plan_seq[k] = sh->seq[k];
                tag.dark_id[k] = dark ? 0 : dark_of(s, sh->cams[k], sh->exposure_us, sh->gain);
                tag.flat_id[k] = dark || flat ? 0 : s->flats[sh->cams[k]];
        }
        if (s->ref_takes > 0 && !dark)
                return; /* the dark or flat rows it names are not stored yet: on_ref_taken */
        s->exposing = true;
        s->takes++;
        s->ref_takes += dark || flat;
        r = capture_take(s->m->capture, sh->cams, sh->n, &req, &tag,
                         dark || flat ? on_ref_taken : on_taken, s);
        if (r >= 0)
                return;
        s->exposing = false;
        s->takes--;
        s->ref_takes -= dark || flat;
        if (r != -EAGAIN) /* -EAGAIN: the storage queue is full; a store's answer calls back */
                set_error(s, r, "capture refused: %s",
                          r == -EBUSY ? rig_busy_reason(s->m->rig) : strerror(-r));
}

static void begin_stop(struct session_runner *s, enum sstate st);

static void step_running(struct session_runner *s)
{
        if (s->ops > 0 || s->exposing)
                return;
        if (s->error < 0 || s->pause_req || s->abort_req)
                return begin_stop(s, s->abort_req ? S_ENDING : S_PAUSING);
        if (s->next == s->n_shots)
                return begin_stop(s, S_ENDING);
        if (!s->positioned)
                return position(s);
        expose(s);
        if (s->error < 0)
                step(s);
}

static void step_preparing(struct session_runner *s)
{
        if (s->ops > 0)
                return;
        if (s->error < 0 || s->pause_req || s->abort_req) {
                answer(s, s->error < 0 ? s->error : -ECANCELED,
                       s->error < 0 ? s->reason : "paused or aborted before it ran");
                return begin_stop(s, s->abort_req ? S_ENDING : S_PAUSING);
        }
        set_state(s, S_RUNNING);
        answer(s, 0, NULL);
        step(s);
}

/* ---- pausing and ending ---- */

/* True when the session paused for a cause that can go away by itself: a device fault (the
 * device comes back), a full disk (space is freed), a drive that lost its home. Not after a
 * client's pause or stop. */
static bool retry_worth(const struct session_runner *s)
{
        if (s->pause_req || s->abort_req || s->error >= 0)
                return false;
        return strcmp(rig_state(s->m->rig), "fault") == 0 || s->error != -ECANCELED;
}

/* Bytes the next shot's frames take uncompressed, times the margin. */
static uint64_t space_needed(const struct session_runner *s)
{
        const struct run_shot *sh = s->next < s->n_shots ? &s->shots[s->next] : NULL;
        uint64_t bytes = 0;

        for (size_t k = 0; sh && k < sh->n; k++) {
                const struct rig_camera_conf *c = &rc_of(s)->cameras[sh->cams[k]];
                bytes += (uint64_t)c->width * c->height * 3 * (c->bits > 8 ? 2 : 1);
        }
        return SPACE_MARGIN * bytes;
}

/* True when the dataset's file system has room for the next shot. */
static bool space_for_next(const struct session_runner *s)
{
        char path[PATH_MAX];
        struct statvfs st;

        if (datasets_path(s->m, s->dataset, path, sizeof(path)) < 0 || statvfs(path, &st) < 0)
                return true; /* let the resume find out */
        return (uint64_t)st.f_bavail * st.f_frsize >= space_needed(s);
}

static int on_retry(sd_event_source *es, uint64_t usec, void *userdata)
{
        struct session_runner *s = userdata;
        char msg[256];
        bool storage = s->error == -ENOSPC || s->error == -EDQUOT || s->error == -EFBIG;

        if (s->state != S_PAUSED)
                return 0;
        if ((storage && !space_for_next(s)) ||
            session_resume(s, NULL, NULL, NULL, msg, sizeof(msg)) < 0)
                return sd_event_source_set_time_relative(es, RETRY_USEC) < 0
                               ? 0
                               : sd_event_source_set_enabled(es, SD_EVENT_ONESHOT);
        log_info("session '%s': resuming after '%s'", s->name, s->reason);
        return 0;
}

/* After a pause with a cause that can go away, tries to resume every RETRY_USEC. */
static void arm_retry(struct session_runner *s)
{
        int r;

        if (!retry_worth(s))
                return;
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        r = sd_event_add_time_relative(s->m->event, &s->retry_timer, CLOCK_MONOTONIC, RETRY_USEC,
                                       100000, on_retry, s);
        if (r < 0)
                log_warning("session '%s': cannot arm the resume timer: %s", s->name, strerror(-r));
}

/* What a pause or the end records in the index, on the dataset worker. */
struct record_job {
        struct session_runner *s;
        struct ds *d; /* borrowed (pause) or taken (end: closed here) */
        bool end;
        char name[DS_NAME_MAX], state[16], reason[256];
        char data_dir[PATH_MAX]; /* for the dark library */
        const struct rig_config *rc;
        char msg[300];
};

/* The light direction of a row in the object frame, for the .lp files. */
static int row_light_dir(const struct ds_capture *c, double dir[3], void *userdata)
{
        const struct rig_config *rc = userdata;

        if (c->pose.lamps == 0)
                return -ENOENT;
        riggeom_lamp_dir_object(rc, __builtin_ctz(c->pose.lamps), &c->pose, dir);
        return 0;
}

/* Adds the session's dark frames to the data directory's dark library (a failure is logged:
 * the session's own rows are not at stake). */
static void share_darks(struct record_job *j)
{
        struct ds *lib = NULL;
        int r = ds_library_open(j->data_dir, true, &lib);

        if (r >= 0)
                r = ds_library_add_darks(lib, j->d, j->name);
        if (r < 0)
                log_warning("session '%s': cannot add its dark frames to the library: %s", j->name,
                            strerror(-r));
        ds_close(lib);
}

static int record_job_run(void *userdata)
{
        struct record_job *j = userdata;
        int r = ds_session_set_state(j->d, j->name, j->state, j->reason);

        if (r >= 0 && strcmp(j->state, "done") == 0)
                r = ds_write_lp(j->d, j->name, row_light_dir, (void *)j->rc);
        if (r >= 0 && j->end)
                share_darks(j);
        if (r < 0)
                snprintf(j->msg, sizeof(j->msg), "dataset '%s': cannot record the session's %s: %s",
                         ds_name(j->d), j->state,
                         ds_last_error(j->d)[0] ? ds_last_error(j->d) : strerror(-r));
        if (j->end)
                j->d = ds_close(j->d);
        return r;
}

static void record_done(int result, void *userdata)
{
        struct record_job *j = userdata;
        struct session_runner *s = j->s;

        s->m->ds_busy = false;
        if (result < 0 && result != -ECANCELED)
                log_error("%s", j->msg);
        if (j->end) {
                snprintf(s->ended, sizeof(s->ended), "%s", j->state);
                log_info("session '%s' %s: %" PRId64 " of %" PRId64 " captures%s%s", s->name,
                         j->state, s->captured, s->planned, s->reason[0] ? ": " : "", s->reason);
                free(s->shots);
                s->shots = NULL;
                s->n_shots = s->next = 0;
                set_state(s, S_NONE);
        } else {
                set_state(s, S_PAUSED);
                arm_retry(s);
        }
        free(j);
}

/* Records the pause or the end of the session (state: "paused", "done", "aborted"). */
static void record(struct session_runner *s, const char *state)
{
        struct manager *m = s->m;
        struct record_job *j = calloc(1, sizeof(*j));
        bool end = strcmp(state, "paused") != 0;
        int64_t count;

        if (!j || !capture_dataset(m->capture) || m->ds_busy) {
                free(j);
                log_error("session '%s': cannot record it as %s", s->name, state);
                return set_state(s, end ? S_NONE : S_PAUSED);
        }
        *j = (struct record_job){.s = s, .end = end, .rc = m->rc};
        snprintf(j->data_dir, sizeof(j->data_dir), "%s", m->data_dir);
        snprintf(j->name, sizeof(j->name), "%s", s->name);
        snprintf(j->state, sizeof(j->state), "%s", state);
        snprintf(j->reason, sizeof(j->reason), "%s", s->reason);
        count = capture_dataset_count(m->capture);
        j->d = end ? capture_detach(m->capture) : capture_dataset(m->capture);
        if (datasets_push(m, record_job_run, record_done, j) < 0) {
                log_error("session '%s': the dataset worker is busy; not recorded as %s", s->name,
                          state);
                if (end) /* the dataset stays open rather than being closed on the loop */
                        (void)datasets_attach(m, j->d, s->dataset, count);
                return record_done(-EAGAIN, j);
        }
        m->ds_busy = true;
}

static void begin_stop(struct session_runner *s, enum sstate st)
{
        if (st == S_PAUSING && s->error >= 0 && !s->reason[0])
                snprintf(s->reason, sizeof(s->reason), "paused by a client");
        if (st == S_ENDING && s->abort_req)
                snprintf(s->reason, sizeof(s->reason), "aborted by a client");
        s->lights_off = false;
        set_state(s, st);
        step(s);
}

/* Pausing or ending: once nothing is in flight, lamps and laser off, then the record. */
static void step_stopping(struct session_runner *s)
{
        if (!drained(s))
                return;
        if (s->state == S_ENDING && !s->abort_req && s->error >= 0 && s->captured < s->planned)
                set_error(s, -EIO, "%" PRId64 " planned captures are missing",
                          s->planned - s->captured);
        if (s->state == S_ENDING && !s->abort_req && s->error < 0)
                return begin_stop(s, S_PAUSING); /* a store failed at the end: resume it */
        if (!s->lights_off) {
                struct gn_pose now = rig_pose(s->m->rig);

                s->lights_off = true;
                light(s, NULL, &now);
                if (s->ops > 0)
                        return;
        }
        record(s, s->state == S_PAUSING ? "paused" : s->abort_req ? "aborted" : "done");
}

static void step(struct session_runner *s)
{
        switch (s->state) {
        case S_PREPARING:
                return step_preparing(s);
        case S_RUNNING:
                return step_running(s);
        case S_PAUSING:
        case S_ENDING:
                return step_stopping(s);
        default:
                return;
        }
}

/* ---- requests ---- */

int session_pause(struct session_runner *s, char *msg, size_t len)
{
        if (s->state == S_NONE)
                return snprintf(msg, len, "no session is running"), -ENOENT;
        if (s->state == S_PAUSED || s->state == S_PAUSING || s->pause_req)
                return snprintf(msg, len, "session '%s' is %s already", s->name,
                                state_names[s->state]),
                       -EALREADY;
        if (s->state == S_ENDING || s->state == S_LOADING)
                return snprintf(msg, len, "session '%s' is %s", s->name, state_names[s->state]),
                       -EBUSY;
        s->pause_req = true;
        step(s);
        return 0;
}

int session_abort(struct session_runner *s, char *msg, size_t len)
{
        if (s->state == S_NONE)
                return snprintf(msg, len, "no session is running"), -ENOENT;
        if (s->state == S_ENDING || s->state == S_LOADING)
                return snprintf(msg, len, "session '%s' is %s", s->name, state_names[s->state]),
                       -EBUSY;
        s->abort_req = true;
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        if (s->state == S_PAUSED) {
                snprintf(s->reason, sizeof(s->reason), "aborted by a client");
                s->lights_off = true;
                set_state(s, S_ENDING);
        } else {
                (void)rig_stop(s->m->rig, NULL); /* the moves in flight end with -ECANCELED */
        }
        step(s);
        return 0;
}

int session_runner_new(struct manager *m, struct session_runner **ret)
{
        struct session_runner *s = calloc(1, sizeof(*s));

        if (!s)
                return -ENOMEM;
        s->m = m;
        *ret = s;
        return 0;
}

struct session_runner *session_runner_free(struct session_runner *s)
{
        if (!s)
                return NULL;
        s->settle_timer = sd_event_source_disable_unref(s->settle_timer);
        s->retry_timer = sd_event_source_disable_unref(s->retry_timer);
        free(s->shots);
        free(s);
        return NULL;
}
