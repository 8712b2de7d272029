/* session_load.c - the session runner's index work, on the dataset worker: planning a
 * session file, recording a new session and its plan (ds_session_begin), loading what a
 * start or resume must capture (ds_plan_pending) with the dark frames and flat fields its
 * rows name, the data directory's dark library, and recording a pause or the end (with the
 * .lp files). The state machine that runs the shots is in session.c. */
#include <dirent.h>
#include <errno.h>
#include <inttypes.h>
#include <limits.h>
#include <stdarg.h>
#include <string.h>
#include <unistd.h>

#include "common/clock.h"
#include "common/log.h"
#include "common/riggeom.h"
#include "common/sessconf.h"
#include "dataset/ds_session.h"
#include "calcopy.h"
#include "datasets.h"
#include "plan.h"
#include "session_internal.h"

#define SKIPS_LISTED 200
#define ABANDONED    "aborted by a client while not loaded (goniod had restarted)"

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

int session_camera_index(const struct rig_config *rc, const char *name)
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
                int cam = session_camera_index(rc, it->camera);
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
        if ((r = ds_claim(j->d)) < 0) /* what a crash left goes before anything is read */
                return job_fail(j, r, "dataset '%s': %s", j->dataset,
                                r == -EBUSY ? "another process is writing it"
                                            : ds_last_error(j->d));
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
        if (j->begin)
                (void)calcopy_into(rc, ds_path(j->d)); /* a warning when it fails */
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
                int cam = session_camera_index(rc_of(s), it->camera);

                if (cam < 0) {
                        session_set_error(s, -ENOENT, "the plan names camera '%s', not in this rig",
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
                session_answer(s, r, r == -ECANCELED ? "goniod is shutting down" : j->msg);
                session_notify_state(s);
                return load_job_free(j);
        }
        s->planned = j->info.planned;
        s->captured = j->info.captured;
        if (j->abandon) {
                snprintf(s->reason, sizeof(s->reason), "%s", ABANDONED);
                snprintf(s->ended, sizeof(s->ended), "aborted");
                s->t_end_ns = s->t_run_ns = gn_monotonic_ns();
                session_set_state(s, S_NONE);
                session_answer(s, 0, NULL);
                return load_job_free(j);
        }
        memcpy(s->darks, j->darks, sizeof(s->darks));
        memcpy(s->flats, j->flats, sizeof(s->flats));
        s->n_darks = j->n_darks;
        read_settle(s, j->info.file_text);
        load_job_free(j);
        session_prepare(s);
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
        session_set_state(s, S_LOADING);
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
        int r = 0;

        /* the .lp files before the end: a crash while they are written leaves the session
         * unfinished, so its resume claims the dataset (removing the .tmp) and writes them */
        if (strcmp(j->state, "done") == 0)
                r = ds_write_lp(j->d, j->name, row_light_dir, (void *)j->rc);
        if (r >= 0)
                r = ds_session_set_state(j->d, j->name, j->state, j->reason);
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
                s->t_end_ns = gn_monotonic_ns();
                log_info("session '%s' %s: %" PRId64 " of %" PRId64 " captures%s%s", s->name,
                         j->state, s->captured, s->planned, s->reason[0] ? ": " : "", s->reason);
                free(s->shots);
                s->shots = NULL;
                s->n_shots = s->next = 0;
                session_set_state(s, S_NONE);
        } else {
                session_set_state(s, S_PAUSED);
                session_arm_retry(s);
        }
        free(j);
}

/* Records the pause or the end of the session (state: "paused", "done", "aborted"). */
void session_record(struct session_runner *s, const char *state)
{
        struct manager *m = s->m;
        struct record_job *j = calloc(1, sizeof(*j));
        bool end = strcmp(state, "paused") != 0;
        int64_t count;

        if (!j || !capture_dataset(m->capture) || m->ds_busy) {
                free(j);
                log_error("session '%s': cannot record it as %s", s->name, state);
                return session_set_state(s, end ? S_NONE : S_PAUSED);
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
