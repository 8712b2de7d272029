/* datasets.c - the dataset.* methods (see datasets.h): each checks its params on the
 * loop, then opens, closes or reads datasets on the dataset worker, and answers when
 * the worker is done.
 *
 * DESIGN
 * Opening, creating and closing a dataset fsync files and migrate or checkpoint its
 * SQLite index; listing opens every dataset of the data directory. None of it may run
 * on the event loop, so each request becomes a job on one common/workq worker ("ds-ops",
 * created on first use, bounded: -EAGAIN when full). While the loop serves, it is
 * marked with ds_forbid_thread() (manager_run), so a ds_ call that does I/O on it aborts
 * builds with assertions, which every e2e test runs.
 *
 * Ownership during open and close: the loop detaches the open dataset from the capture
 * pipeline (capture_detach: its storage pool is idle, as no capture is in flight, and is
 * freed; captures and status then see no dataset) and hands it to the job. The worker opens the
 * new one and only then closes the old; on failure the old one comes back on the loop.
 * One open or close runs at a time (m->ds_busy); list and info read their own handles
 * and may queue behind it. Read results are built as JSON on the worker and handed to
 * the loop with the completion. */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <string.h>

#include "common/log.h"
#include "calcopy.h"
#include "common/workq.h"
#include "datasets.h"
#include "manager.h"

#define KEYS(...)        ((const char *const[]){__VA_ARGS__, NULL})
#define INFO_LAST_ROWS   20
#define DS_OPS_QUEUE     8
#define DS_NAME_ALPHABET "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-"

/* One dataset request, owned by the worker from push to completion. */
struct ds_job {
        struct manager *m;
        struct srv_req *req;
        char path[PATH_MAX];
        char name[DS_NAME_MAX];
        bool create;                /* open: create it */
        struct ds *old;             /* open/close: the dataset that was open */
        char old_name[DS_NAME_MAX]; /* its name and rows, to put it back */
        int64_t old_count;
        struct ds *d;   /* open: the new dataset */
        int64_t count;  /* open: its rows */
        json_t *result; /* list/info: the answer */
        char msg[300];  /* why it failed */
};

static json_t *num_or_null(double v)
{
        return isnan(v) ? json_null() : json_real(v);
}

json_t *datasets_row_json(const struct ds_capture *c)
{
        return json_pack("{sIsssssssisisssosososssbsI}", "id", (json_int_t)c->id, "camera",
                         c->camera, "file", c->file, "sha256", c->sha256, "width", c->width,
                         "height", c->height, "pixfmt", c->pixfmt, "turntable",
                         num_or_null(c->pose.deg[GN_ROLE_TURNTABLE]), "light_arm",
                         num_or_null(c->pose.deg[GN_ROLE_LIGHT_ARM]), "camera_arm",
                         num_or_null(c->pose.deg[GN_ROLE_CAMERA_ARM]), "lamps", c->lamps, "laser",
                         c->pose.lasers != 0, "lasers", (json_int_t)c->pose.lasers);
}

/* ---- jobs (worker thread) ---- */

static int open_job(void *userdata)
{
        struct ds_job *j = userdata;
        int r;

        r = j->create ? ds_create(j->path, j->name, j->m->rc->text, &j->d)
                      : ds_open(j->path, &j->d);
        if (r < 0) {
                snprintf(j->msg, sizeof(j->msg), "%s dataset '%s': %s",
                         j->create ? "cannot create" : "cannot open", j->name,
                         r == -EEXIST   ? "it exists already"
                         : r == -ENOENT ? "no such dataset"
                                        : strerror(-r));
                return r;
        }
        if (j->old && strcmp(ds_path(j->old), ds_path(j->d)) == 0)
                j->old = ds_close(j->old); /* reopened: its lock would refuse the claim */
        if ((r = ds_claim(j->d)) < 0) {    /* what a crash left goes now */
                snprintf(j->msg, sizeof(j->msg), "cannot open dataset '%s': %s", j->name,
                         r == -EBUSY ? "another process is writing it" : ds_last_error(j->d));
                j->d = ds_close(j->d);
                return r;
        }
        if (j->create)
                (void)calcopy_into(j->m->rc, ds_path(j->d)); /* a warning when it fails */
        j->count = ds_count(j->d);
        j->old = ds_close(j->old);
        return 0;
}

static int close_job(void *userdata)
{
        struct ds_job *j = userdata;

        j->old = ds_close(j->old);
        return 0;
}

static int add_row(const struct ds_capture *c, void *userdata)
{
        return json_array_append_new(userdata, datasets_row_json(c)) == 0 ? 0 : -ENOMEM;
}

/* {name, path, count, created, rig} of a summary, plus cameras and the last rows with
 * rows. */
static json_t *summary_json(struct ds *d, const struct ds_summary *s, bool rows)
{
        json_t *out = json_pack("{sssssIssss}", "name", s->name, "path", ds_path(d), "count",
                                (json_int_t)s->captures, "created", s->created, "rig", s->rig);
        json_t *cams = json_array(), *caps = json_array();

        if (!rows || !out || !cams || !caps) {
                json_decref(cams);
                json_decref(caps);
                return out;
        }
        for (size_t i = 0; i < s->n_cameras; i++)
                json_array_append_new(cams, json_string(s->cameras[i].name));
        (void)ds_rows(d, MAX(s->last_id - INFO_LAST_ROWS, 0), INFO_LAST_ROWS, add_row, caps);
        json_object_set_new(out, "cameras", cams);
        json_object_set_new(out, "captures", caps);
        return out;
}

/* The summary of the dataset at path as JSON; NULL if it is not a dataset. The name is
 * the directory's (what dataset.open takes), not the one recorded at creation. */
static json_t *dataset_json(const char *path, const char *name, bool rows)
{
        struct ds_summary s;
        struct ds *d = NULL;
        json_t *out = NULL;

        if (ds_open(path, &d) < 0)
                return NULL;
        if (ds_summary(d, &s) == 0) {
                snprintf(s.name, sizeof(s.name), "%s", name);
                out = summary_json(d, &s, rows);
        }
        ds_close(d);
        return out;
}

static int info_job(void *userdata)
{
        struct ds_job *j = userdata;

        j->result = dataset_json(j->path, j->name, true);
        if (!j->result) {
                snprintf(j->msg, sizeof(j->msg), "no dataset named '%s'", j->name);
                return -ENOENT;
        }
        return 0;
}

static void add_problem(const char *problem, void *userdata)
{
        json_array_append_new(userdata, json_string(problem));
}

/* ds_check on a handle of its own (the writer may be storing meanwhile). */
static int check_job(void *userdata)
{
        struct ds_job *j = userdata;
        json_t *problems = json_array();
        struct ds *d = NULL;
        int r = ds_open(j->path, &d);

        if (r >= 0 && problems)
                r = ds_check(d, add_problem, problems);
        if (r < 0)
                snprintf(j->msg, sizeof(j->msg), "cannot check dataset '%s': %s", j->name,
                         r == -ENOENT ? "no such dataset" : strerror(-r));
        else
                j->result = json_pack("{sssssIso}", "name", j->name, "path", ds_path(d), "count",
                                      (json_int_t)ds_count(d), "problems", problems);
        ds_close(d);
        if (r < 0)
                json_decref(problems);
        return r < 0 ? r : 0;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(DIR *, closedir);

static int list_job(void *userdata)
{
        struct ds_job *j = userdata;
        _cleanup_(closedirp) DIR *dir = opendir(j->m->data_dir);
        json_t *list;
        struct dirent *de;

        if (!dir) {
                int r = -errno;

                snprintf(j->msg, sizeof(j->msg), "cannot read %s: %s", j->m->data_dir,
                         strerror(-r));
                return r;
        }
        list = json_array();
        while (list && (de = readdir(dir))) {
                char path[PATH_MAX];
                json_t *info;

                if (de->d_name[0] == '.' ||
                    (size_t)snprintf(path, sizeof(path), "%s/%s", j->m->data_dir, de->d_name) >=
                            sizeof(path))
                        continue;
                info = dataset_json(path, de->d_name, false);
                if (info)
                        json_array_append_new(list, info);
        }
        j->result = json_pack("{so}", "datasets", list);
        return j->result ? 0 : -ENOMEM;
}

/* ---- completions and requests (loop thread) ---- */

static void job_free(struct ds_job *j)
{
        json_decref(j->result);
        free(j);
}

int datasets_push(struct manager *m, workq_fn fn, workq_done_fn done, void *userdata)
{
        int r = 0;

        if (!m->ds_worker)
                r = workq_new(m->event, "ds-ops", DS_OPS_QUEUE, &m->ds_worker);
        if (r == 0)
                r = workq_push(m->ds_worker, fn, done, userdata, false);
        return r;
}

/* Queues j on the dataset worker. */
static int push(struct ds_job *j, workq_fn fn, workq_done_fn done)
{
        return datasets_push(j->m, fn, done, j);
}

static void closed_done(int result, void *userdata)
{
        struct ds_job *j = userdata;

        if (j->old) /* cancelled at shutdown, after the loop stopped serving */
                j->old = ds_close(j->old);
        if (j->req)
                srv_reply(j->req, json_object());
        j->m->ds_busy = false;
        job_free(j);
}

/* Closes d on the worker, answering nobody; at once when the loop has finished (shutdown:
 * a load that completed as goniod stopped), since no worker takes jobs any more and the
 * loop's thread may block again. */
static void close_later(struct manager *m, struct ds *d)
{
        struct ds_job *j;

        if (sd_event_get_state(m->event) == SD_EVENT_FINISHED) {
                ds_close(d);
                return;
        }
        j = calloc(1, sizeof(*j));
        if (j) {
                *j = (struct ds_job){.m = m, .old = d};
                m->ds_busy = true;
                if (push(j, close_job, closed_done) == 0)
                        return;
                m->ds_busy = false;
                free(j);
        }
        log_error("Cannot close dataset '%s' off the event loop; leaving it open", ds_path(d));
}

int datasets_attach(struct manager *m, struct ds *d, const char *name, int64_t count)
{
        int r;

        /* goniod is shutting down (an open finished as it stopped): no pool can start */
        if (sd_event_get_state(m->event) == SD_EVENT_FINISHED)
                r = -ECANCELED;
        else
                r = capture_attach(m->capture, d, name, count);
        if (r < 0)
                close_later(m, d);
        return r;
}

static void opened_done(int result, void *userdata)
{
        struct ds_job *j = userdata;
        struct manager *m = j->m;
        int r;

        m->ds_busy = false;
        if (result < 0 && j->old)
                (void)datasets_attach(m, TAKE_PTR(j->old), j->old_name, j->old_count);
        if (result == -ECANCELED) {
                j->d = ds_close(j->d);
                srv_fail(j->req, result, "goniod is shutting down");
        } else if (result < 0) {
                srv_fail(j->req, result, "%s", j->msg);
        } else if ((r = datasets_attach(m, TAKE_PTR(j->d), j->name, j->count)) == -ECANCELED) {
                srv_fail(j->req, r, "goniod is shutting down");
        } else if (r < 0) {
                srv_fail(j->req, r, "cannot start the storage pool: %s", strerror(-r));
        } else {
                srv_reply(j->req,
                          json_pack("{sssssI}", "path", ds_path(capture_dataset(m->capture)),
                                    "name", j->name, "count",
                                    (json_int_t)capture_dataset_count(m->capture)));
        }
        job_free(j);
}

/* Answers a list or info job with its result. */
static void read_done(int result, void *userdata)
{
        struct ds_job *j = userdata;

        if (result < 0)
                srv_fail(j->req, result, "%s", result == -ECANCELED ? "cancelled" : j->msg);
        else
                srv_reply(j->req, TAKE_PTR(j->result));
        job_free(j);
}

/* Answers a check: its result when clean, else an error whose data lists the problems. */
static void checked_done(int result, void *userdata)
{
        struct ds_job *j = userdata;
        json_t *problems = json_object_get(j->result, "problems");
        size_t n = json_array_size(problems);

        if (result >= 0 && n > 0) {
                srv_fail_data(j->req, -EBADMSG, json_pack("{sO}", "problems", problems),
                              "dataset '%s': %zu problem%s, the first: %s", j->name, n,
                              n == 1 ? "" : "s", json_string_value(json_array_get(problems, 0)));
                return job_free(j);
        }
        read_done(result, j);
}

int datasets_path(const struct manager *m, const char *name, char *path, size_t len)
{
        if (!name || !name[0] || name[0] == '.' || strlen(name) >= DS_NAME_MAX ||
            strspn(name, DS_NAME_ALPHABET) != strlen(name))
                return -EINVAL;
        if ((size_t)snprintf(path, len, "%s/%s", m->data_dir, name) >= len)
                return -ENAMETOOLONG;
        return 0;
}

/* datasets_path, answering req with why a name is refused. */
static int dataset_path(struct srv_req *req, struct manager *m, const char *name, char *path,
                        size_t len)
{
        int r = datasets_path(m, name, path, len);

        if (r == -EINVAL)
                return srv_req_errmsg(req, r,
                                      "param 'name': '%s' is not a valid dataset name "
                                      "(letters, digits, '.', '_', '-')",
                                      name ? name : "");
        if (r < 0)
                return srv_req_errmsg(req, r, "dataset path too long");
        return 0;
}

/* Why the open dataset cannot change now (0: it can). */
static int busy(struct srv_req *req, const struct manager *m)
{
        if (session_active(m->session))
                return srv_req_errmsg(req, -EBUSY, "%s", session_busy_reason(m->session));
        if (scan_active(m->scan))
                return srv_req_errmsg(req, -EBUSY, "%s", scan_busy_reason(m->scan));
        if (m->ds_busy)
                return srv_req_errmsg(req, -EBUSY, "another dataset.open or close is running");
        if (capture_in_flight(m->capture) > 0)
                return srv_req_errmsg(req, -EBUSY, "captures are still in progress");
        return 0;
}

/* A new job for req, or NULL (-ENOMEM). */
static struct ds_job *job_new(struct manager *m, struct srv_req *req)
{
        struct ds_job *j = calloc(1, sizeof(*j));

        if (j) {
                j->m = m;
                j->req = req;
        }
        return j;
}

/* Queues a job that replaces or closes the open dataset, which it takes over. */
static int push_change(struct ds_job *j, workq_fn fn, workq_done_fn done)
{
        struct manager *m = j->m;
        int r;

        snprintf(j->old_name, sizeof(j->old_name), "%s",
                 capture_dataset(m->capture) ? capture_dataset_name(m->capture) : "");
        j->old_count = capture_dataset_count(m->capture);
        j->old = capture_detach(m->capture);
        r = push(j, fn, done);
        if (r < 0) {
                struct srv_req *req = j->req;

                if (j->old)
                        (void)datasets_attach(m, j->old, j->old_name, j->old_count);
                free(j);
                return srv_req_errmsg(req, r, "the dataset worker is busy");
        }
        m->ds_busy = true;
        return 0;
}

int datasets_open(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *name = NULL;
        bool create = false;
        struct ds_job *j;
        char path[PATH_MAX];
        int r;

        if ((r = srv_params_check(req, params, KEYS("name", "create"))) < 0 ||
            (r = srv_param_str(req, params, "name", &name)) < 0 ||
            (r = srv_param_bool(req, params, "create", &create)) < 0 ||
            (r = dataset_path(req, m, name, path, sizeof(path))) < 0 || (r = busy(req, m)) < 0)
                return r;
        if (!(j = job_new(m, req)))
                return -ENOMEM;
        snprintf(j->path, sizeof(j->path), "%s", path);
        snprintf(j->name, sizeof(j->name), "%s", name);
        j->create = create;
        return push_change(j, open_job, opened_done);
}

int datasets_close(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        struct ds_job *j;
        int r;

        if ((r = busy(req, m)) < 0)
                return r;
        if (!capture_dataset(m->capture)) {
                srv_reply(req, json_object());
                return 0;
        }
        if (!(j = job_new(m, req)))
                return -ENOMEM;
        return push_change(j, close_job, closed_done);
}

/* Queues a read job; the request is answered with its result (by done, else read_done). */
static int push_read(struct ds_job *j, workq_fn fn, workq_done_fn done)
{
        int r = push(j, fn, done ? done : read_done);

        if (r < 0) {
                struct srv_req *req = j->req;
                free(j);
                return srv_req_errmsg(req, r, "the dataset worker is busy");
        }
        return 0;
}

int datasets_list(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        struct ds_job *j;
        int r;

        if ((r = srv_params_check(req, params, KEYS(NULL))) < 0)
                return r;
        if (!(j = job_new(m, req)))
                return -ENOMEM;
        return push_read(j, list_job, NULL);
}

/* Queues a read job fn on dataset name (NULL: the open one, when open_ok) for req. */
static int push_named(struct srv_req *req, struct manager *m, const char *name, bool open_ok,
                      workq_fn fn, workq_done_fn done)
{
        struct ds_job *j;
        char path[PATH_MAX];
        int r;

        if (!name && open_ok && !capture_dataset(m->capture))
                return srv_req_errmsg(req, -ENOENT, "no dataset is open and no name given");
        if (!name && open_ok)
                name = capture_dataset_name(m->capture);
        if ((r = dataset_path(req, m, name, path, sizeof(path))) < 0)
                return r;
        if (!(j = job_new(m, req)))
                return -ENOMEM;
        snprintf(j->path, sizeof(j->path), "%s", path);
        snprintf(j->name, sizeof(j->name), "%s", name);
        return push_read(j, fn, done);
}

int datasets_info(struct srv_req *req, json_t *params, void *userdata)
{
        const char *name = NULL;
        int r;

        if ((r = srv_params_check(req, params, KEYS("name"))) < 0 ||
            (r = srv_param_str(req, params, "name", &name)) < 0)
                return r;
        return push_named(req, userdata, name, true, info_job, NULL);
}

int datasets_check(struct srv_req *req, json_t *params, void *userdata)
{
        const char *name = NULL;
        int r;

        if ((r = srv_params_check(req, params, KEYS("name"))) < 0 ||
            (r = srv_param_str(req, params, "name", &name)) < 0)
                return r;
        return push_named(req, userdata, name, false, check_job, checked_done);
}

void datasets_free(struct manager *m)
{
        m->ds_worker = workq_free(m->ds_worker);
}
