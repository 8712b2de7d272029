/* datasets.c - the dataset.* methods (see datasets.h): each checks its params, then
 * opens, closes or reads datasets through the dataset library's read API (summary and
 * the last rows; nothing parses dataset.json or walks a whole index). */
#include <dirent.h>
#include <errno.h>
#include <math.h>
#include <string.h>

#include "common/log.h"
#include "datasets.h"
#include "manager.h"

#define KEYS(...)        ((const char *const[]){__VA_ARGS__, NULL})
#define INFO_LAST_ROWS   20
#define DS_NAME_ALPHABET "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789._-"

static json_t *num_or_null(double v)
{
        return isnan(v) ? json_null() : json_real(v);
}

json_t *datasets_row_json(const struct ds_capture *c)
{
        return json_pack("{sIsssssssisisssosososssb}", "id", (json_int_t)c->id, "camera", c->camera,
                         "file", c->file, "sha256", c->sha256, "width", c->width, "height",
                         c->height, "pixfmt", c->pixfmt, "turntable",
                         num_or_null(c->pose.deg[GN_ROLE_TURNTABLE]), "light_arm",
                         num_or_null(c->pose.deg[GN_ROLE_LIGHT_ARM]), "camera_arm",
                         num_or_null(c->pose.deg[GN_ROLE_CAMERA_ARM]), "lamps", c->lamps, "laser",
                         c->pose.laser);
}

/* A dataset name is one path component of [A-Za-z0-9._-], not starting with '.'. */
static int dataset_path(struct srv_req *req, struct manager *m, const char *name, char *path,
                        size_t len)
{
        if (!name || !name[0] || name[0] == '.' || strlen(name) >= DS_NAME_MAX ||
            strspn(name, DS_NAME_ALPHABET) != strlen(name))
                return srv_req_errmsg(req, -EINVAL,
                                      "param 'name': '%s' is not a valid dataset name "
                                      "(letters, digits, '.', '_', '-')",
                                      name ? name : "");
        if ((size_t)snprintf(path, len, "%s/%s", m->data_dir, name) >= len)
                return srv_req_errmsg(req, -ENAMETOOLONG, "dataset path too long");
        return 0;
}

/* True while a capture is being taken or stored: the dataset must not change under it. */
static bool storing(const struct manager *m)
{
        return strcmp(rig_state(m->rig), "capturing") == 0 ||
               (m->pool && ds_pool_in_flight(m->pool) > 0);
}

static void dataset_close(struct manager *m)
{
        m->pool = ds_pool_free(m->pool);
        m->ds = ds_close(m->ds);
        m->ds_name[0] = 0;
        m->ds_count = 0;
}

int datasets_open(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *name = NULL;
        bool create = false;
        char path[PATH_MAX];
        struct ds *d = NULL;
        int r;

        if ((r = srv_params_check(req, params, KEYS("name", "create"))) < 0 ||
            (r = srv_param_str(req, params, "name", &name)) < 0 ||
            (r = srv_param_bool(req, params, "create", &create)) < 0 ||
            (r = dataset_path(req, m, name, path, sizeof(path))) < 0)
                return r;
        if (storing(m))
                return srv_req_errmsg(req, -EBUSY, "captures are still in progress");
        r = create ? ds_create(path, name, m->rc->text, &d) : ds_open(path, &d);
        if (r < 0)
                return srv_req_errmsg(req, r, "%s dataset '%s': %s",
                                      create ? "cannot create" : "cannot open", name,
                                      r == -EEXIST   ? "it exists already"
                                      : r == -ENOENT ? "no such dataset"
                                                     : strerror(-r));
        dataset_close(m);
        r = ds_pool_new(m->event, d, 2, 16, &m->pool);
        if (r < 0) {
                ds_close(d);
                return srv_req_errmsg(req, r, "cannot start the storage pool: %s", strerror(-r));
        }
        m->ds = d;
        m->ds_count = ds_count(d);
        snprintf(m->ds_name, sizeof(m->ds_name), "%s", name);
        srv_reply(req, json_pack("{sssssI}", "path", ds_path(d), "name", name, "count",
                                 (json_int_t)m->ds_count));
        return 0;
}

int datasets_close(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;

        if (storing(m))
                return srv_req_errmsg(req, -EBUSY, "captures are still in progress");
        dataset_close(m);
        srv_reply(req, json_object());
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

int datasets_list(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        DIR *dir = opendir(m->data_dir);
        json_t *list = json_array();
        struct dirent *de;

        if (!dir)
                return json_decref(list),
                       srv_req_errmsg(req, -errno, "cannot read %s: %m", m->data_dir);
        while ((de = readdir(dir))) {
                char path[PATH_MAX];
                json_t *info;

                if (de->d_name[0] == '.' ||
                    (size_t)snprintf(path, sizeof(path), "%s/%s", m->data_dir, de->d_name) >=
                            sizeof(path))
                        continue;
                info = dataset_json(path, de->d_name, false);
                if (info)
                        json_array_append_new(list, info);
        }
        closedir(dir);
        srv_reply(req, json_pack("{so}", "datasets", list));
        return 0;
}

int datasets_info(struct srv_req *req, json_t *params, void *userdata)
{
        struct manager *m = userdata;
        const char *name = NULL;
        char path[PATH_MAX];
        json_t *info;
        int r;

        if ((r = srv_params_check(req, params, KEYS("name"))) < 0 ||
            (r = srv_param_str(req, params, "name", &name)) < 0)
                return r;
        if (!name && !m->ds)
                return srv_req_errmsg(req, -ENOENT, "no dataset is open and no name given");
        if (!name)
                name = m->ds_name;
        if ((r = dataset_path(req, m, name, path, sizeof(path))) < 0)
                return r;
        info = dataset_json(path, name, true);
        if (!info)
                return srv_req_errmsg(req, -ENOENT, "no dataset named '%s'", name);
        srv_reply(req, info);
        return 0;
}
