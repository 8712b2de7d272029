/* model_io.c - the appearance model on disk (model.h): models/<name>/ of a dataset with
 * model.json (jansson), basis.f32 and the views' weight and mask PNGs (model_png.h); written
 * into a temporary directory that is renamed into place, read back with every problem named
 * by file. docs/appearance.md, "Files". */
#include <dirent.h>
#include <errno.h>
#include <libgen.h>
#include <limits.h>
#include <fcntl.h>
#include <jansson.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "appearance/io_internal.h"
#include "appearance/model.h"
#include "appearance/model_png.h"
#include "common/cleanup.h"
#include "common/fileio.h"

#define MODEL_VERSION 1
#define MODEL_FORMAT  "gonio-appearance 1"
#define Q_MAX         65535.0f

struct ap_model *ap_model_free(struct ap_model *m)
{
        if (!m)
                return NULL;
        for (size_t i = 0; m->views && i < m->n_views; i++) {
                free(m->views[i].weights);
                free(m->views[i].mask);
        }
        free(m->views);
        free(m->mean);
        free(m->basis);
        free(m);
        return NULL;
}

int ap_model_new(int order, int k, size_t n_views, struct ap_model **ret)
{
        struct ap_model *m;
        size_t n3 = 3 * (size_t)ap_n_coef(order);

        if (order < 1 || order > AP_ORDER_MAX || k < 1 || k > AP_K_MAX || n_views == 0)
                return -EINVAL;
        m = calloc(1, sizeof(*m));
        if (!m)
                return -ENOMEM;
        m->order = order;
        m->n_coef = ap_n_coef(order);
        m->k = k;
        m->n_views = n_views;
        m->mean = calloc(n3, sizeof(float));
        m->basis = calloc(n3 * k, sizeof(float));
        m->views = calloc(n_views, sizeof(*m->views));
        if (!m->mean || !m->basis || !m->views) {
                ap_model_free(m);
                return -ENOMEM;
        }
        *ret = m;
        return 0;
}

int ap_view_alloc(struct ap_view *v, int k)
{
        size_t n = (size_t)v->cam.width * v->cam.height;

        if (v->cam.width <= 0 || v->cam.height <= 0)
                return -EINVAL;
        v->weights = calloc(n * k, sizeof(float));
        v->mask = calloc(n, 1);
        return v->weights && v->mask ? 0 : -ENOMEM;
}

/* ---- writing ---- */

json_t *ap_io_json_vec(const double *v, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                json_array_append_new(a, json_real(v[i]));
        return a;
}

static json_t *json_fvec(const float *v, size_t n)
{
        json_t *a = json_array();

        for (size_t i = 0; a && i < n; i++)
                json_array_append_new(a, json_real(v[i]));
        return a;
}

/* A number, or null for NAN (no such axis). */
static json_t *json_angle(double v)
{
        return isnan(v) ? json_null() : json_real(v);
}

json_t *ap_io_camera_json(const struct ap_camera *c)
{
        return json_pack("{s:i,s:i,s:f,s:f,s:f,s:f,s:o,s:o,s:o}", "width", c->width, "height",
                         c->height, "fx", c->fx, "fy", c->fy, "cx", c->cx, "cy", c->cy, "dist",
                         ap_io_json_vec(c->dist, 5), "R", ap_io_json_vec(c->R, 9), "t",
                         ap_io_json_vec(c->t, 3));
}

static json_t *view_json(const struct ap_view *v, int k, const float *scale, const float *offset)
{
        return json_pack("{s:s,s:o,s:o,s:o,s:o,s:o,s:o}", "camera", v->camera, "turntable_deg",
                         json_angle(v->turntable_deg), "camera_arm_deg",
                         json_angle(v->camera_arm_deg), "dir", ap_io_json_vec(v->dir, 3),
                         "geometry", ap_io_camera_json(&v->cam), "scale", json_fvec(scale, k),
                         "offset", json_fvec(offset, k));
}

static json_t *model_json(const struct ap_model *m, json_t *views)
{
        return json_pack("{s:s,s:s,s:i,s:i,s:i,s:s,s:s,s:{s:f,s:f},s:{s:s,s:f,s:f,s:f,s:f},s:o}",
                         "format", MODEL_FORMAT, "name", m->name, "order", m->order, "n_coef",
                         m->n_coef, "components", m->k, "colour", "linear rgb", "notes", m->notes,
                         "light", "distance_mm", m->light_distance_mm, "intensity",
                         m->light_intensity, "fit", "regularisation", m->reg, "parameter",
                         m->reg_param, "rms_sh", m->rms_sh, "rms_pca", m->rms_pca, "seconds",
                         m->fit_seconds, "views", views);
}

/* Writes a new file name in dfd with buf and fsyncs it. Returns 0 or -errno. */
int ap_io_put_file(int dfd, const char *name, const void *buf, size_t len)
{
        _cleanup_close_ int fd = openat(dfd, name, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0644);
        int r;

        if (fd < 0)
                return -errno;
        r = gn_write_all(fd, buf, len, NULL);
        if (r == 0 && fsync(fd) < 0)
                r = -errno;
        return r;
}

void ap_view_range(const struct ap_view *v, int K, int k, float *lo, float *hi)
{
        size_t n = (size_t)v->cam.width * v->cam.height;

        *lo = INFINITY, *hi = -INFINITY;
        for (size_t p = 0; p < n; p++)
                if (v->mask[p]) {
                        *lo = fminf(*lo, v->weights[p * K + k]);
                        *hi = fmaxf(*hi, v->weights[p * K + k]);
                }
        if (!(*lo <= *hi))
                *lo = *hi = 0;
}

/* Quantisation of component k of v's weights inside its mask to 0..65535. */
static void quantisation(const struct ap_view *v, int K, int k, float *scale, float *offset)
{
        float lo, hi;

        ap_view_range(v, K, k, &lo, &hi);
        *offset = lo;
        *scale = hi > lo ? (hi - lo) / Q_MAX : 1;
}

/* Writes views/NNN_wG.png (components 4G..4G+3) of view i. Returns 0 or -errno. */
static int put_weights(int dfd, const struct ap_view *v, size_t i, int K, int g, const float *scale,
                       const float *offset)
{
        size_t n = (size_t)v->cam.width * v->cam.height;
        _cleanup_free_ uint16_t *q = calloc(n * 4, sizeof(uint16_t));
        _cleanup_free_ void *png = NULL;
        char name[64];
        size_t len;
        int r;

        if (!q)
                return -ENOMEM;
        for (size_t p = 0; p < n; p++)
                for (int c = 0; c < 4 && 4 * g + c < K && v->mask[p]; c++) {
                        int k = 4 * g + c;
                        float s = (v->weights[p * K + k] - offset[k]) / scale[k];
                        q[p * 4 + c] = (uint16_t)lrintf(fminf(fmaxf(s, 0), Q_MAX));
                }
        r = ap_png_encode(v->cam.width, v->cam.height, 4, q, NULL, &png, &len);
        if (r < 0)
                return r;
        snprintf(name, sizeof(name), "%03zu_w%d.png", i, g);
        return ap_io_put_file(dfd, name, png, len);
}

static int put_mask(int dfd, const struct ap_view *v, size_t i)
{
        size_t n = (size_t)v->cam.width * v->cam.height;
        _cleanup_free_ uint8_t *m = malloc(n);
        _cleanup_free_ void *png = NULL;
        char name[64];
        size_t len;
        int r;

        if (!m)
                return -ENOMEM;
        for (size_t p = 0; p < n; p++)
                m[p] = v->mask[p] ? 255 : 0;
        r = ap_png_encode(v->cam.width, v->cam.height, 1, NULL, m, &png, &len);
        if (r < 0)
                return r;
        snprintf(name, sizeof(name), "%03zu_mask.png", i);
        return ap_io_put_file(dfd, name, png, len);
}

/* Writes view i's images into views/ (vfd) and its entry into *entry. */
static int put_view(int vfd, const struct ap_model *m, size_t i, json_t **entry)
{
        const struct ap_view *v = &m->views[i];
        float scale[AP_K_MAX], offset[AP_K_MAX];
        int r = 0;

        for (int k = 0; k < m->k; k++)
                quantisation(v, m->k, k, &scale[k], &offset[k]);
        for (int g = 0; r == 0 && 4 * g < m->k; g++)
                r = put_weights(vfd, v, i, m->k, g, scale, offset);
        if (r == 0)
                r = put_mask(vfd, v, i);
        if (r == 0 && !(*entry = view_json(v, m->k, scale, offset)))
                r = -ENOMEM;
        return r;
}

/* The views of a model written by PUT_THREADS threads (the PNG encoding is most of a model's
 * write: bench/fit). */
#define PUT_THREADS 2

struct put_job {
        int vfd;
        const struct ap_model *m;
        json_t **entries; /* one per view */
        size_t next;
        int r; /* the first error */
        pthread_mutex_t lock;
};

static void *put_worker(void *arg)
{
        struct put_job *j = arg;

        for (;;) {
                size_t i;
                int r;
                pthread_mutex_lock(&j->lock);
                i = j->r < 0 ? j->m->n_views : j->next++;
                pthread_mutex_unlock(&j->lock);
                if (i >= j->m->n_views)
                        return NULL;
                r = put_view(j->vfd, j->m, i, &j->entries[i]);
                pthread_mutex_lock(&j->lock);
                j->r = j->r < 0 ? j->r : r;
                pthread_mutex_unlock(&j->lock);
        }
}

/* Writes every view's images into views/ (vfd) and appends their entries to views, in order. */
static int put_views(int vfd, const struct ap_model *m, json_t *views)
{
        _cleanup_free_ json_t **entries = calloc(m->n_views + 1, sizeof(*entries));
        struct put_job j = {vfd, m, entries, 0, 0, PTHREAD_MUTEX_INITIALIZER};
        pthread_t t[PUT_THREADS - 1];
        int n = 0;

        if (!entries)
                return -ENOMEM;
        while (n < PUT_THREADS - 1 && pthread_create(&t[n], NULL, put_worker, &j) == 0)
                n++;
        put_worker(&j);
        while (n > 0)
                pthread_join(t[--n], NULL);
        for (size_t i = 0; i < m->n_views; i++)
                if (entries[i] && json_array_append_new(views, entries[i]) < 0)
                        j.r = j.r < 0 ? j.r : -ENOMEM;
        return j.r;
}

static int put_basis(int dfd, const struct ap_model *m)
{
        size_t n3 = 3 * (size_t)m->n_coef, bytes = n3 * (m->k + 1) * sizeof(float);
        _cleanup_free_ float *b = malloc(bytes);

        if (!b)
                return -ENOMEM;
        /* little-endian on the hosts we build for (x86-64, aarch64) */
        memcpy(b, m->mean, n3 * sizeof(float));
        memcpy(b + n3, m->basis, n3 * m->k * sizeof(float));
        return ap_io_put_file(dfd, "basis.f32", b, bytes);
}

/* Writes every file of m into the empty directory dfd. */
static int put_model(int dfd, const struct ap_model *m)
{
        _cleanup_(json_decrefp) json_t *views = json_array(), *doc = NULL;
        _cleanup_close_ int vfd = -EBADF;
        _cleanup_free_ char *text = NULL;
        int r;

        if (!views)
                return -ENOMEM;
        if (mkdirat(dfd, "views", 0755) < 0)
                return -errno;
        vfd = openat(dfd, "views", O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        if (vfd < 0)
                return -errno;
        r = put_views(vfd, m, views);
        if (r < 0)
                return r;
        if (fsync(vfd) < 0)
                return -errno;
        r = put_basis(dfd, m);
        if (r < 0)
                return r;
        doc = model_json(m, json_incref(views));
        text = doc ? json_dumps(doc, JSON_INDENT(2)) : NULL;
        if (!text)
                return -ENOMEM;
        r = ap_io_put_file(dfd, "model.json", text, strlen(text));
        if (r == 0 && fsync(dfd) < 0)
                r = -errno;
        return r;
}

void ap_model_dataset(const char *dir, char *out, size_t len)
{
        char buf[PATH_MAX];

        if (!realpath(dir, buf))
                snprintf(buf, sizeof(buf), "%s", dir);
        snprintf(out, len, "%s", dirname(dirname(buf)));
}

void ap_remove_tree(const char *path)
{
        DIR *d = opendir(path);
        struct dirent *e;

        while (d && (e = readdir(d))) {
                char sub[4096];
                if (strcmp(e->d_name, ".") == 0 || strcmp(e->d_name, "..") == 0)
                        continue;
                snprintf(sub, sizeof(sub), "%s/%s", path, e->d_name);
                if (e->d_type == DT_DIR)
                        ap_remove_tree(sub);
                else
                        unlink(sub);
        }
        if (d)
                closedir(d);
        rmdir(path);
}

int ap_io_install_dir(const char *tmp, const char *final)
{
        if (renameat2(AT_FDCWD, tmp, AT_FDCWD, final, RENAME_NOREPLACE) == 0)
                return gn_fsync_parent(final);
        if (errno != EEXIST)
                return -errno;
        if (renameat2(AT_FDCWD, tmp, AT_FDCWD, final, RENAME_EXCHANGE) < 0)
                return -errno;
        ap_remove_tree(tmp);
        return gn_fsync_parent(final);
}

/* Hard-links the files of final's BRDF model folder into tmp, so that replacing the SH model
 * keeps it, whenever the writer is killed (a link, not a move: final holds it throughout). */
static int keep_brdf(const char *final, const char *tmp)
{
        char from[4300], to[4300], file[4600];
        DIR *d;
        struct dirent *e;
        int r = 0;

        snprintf(from, sizeof(from), "%s/%s", final, AP_IO_BRDF_DIR);
        snprintf(to, sizeof(to), "%s/%s", tmp, AP_IO_BRDF_DIR);
        if (!(d = opendir(from)))
                return errno == ENOENT ? 0 : -errno;
        if (mkdir(to, 0755) < 0)
                r = -errno;
        while (r == 0 && (e = readdir(d))) {
                if (e->d_name[0] == '.')
                        continue;
                snprintf(file, sizeof(file), "%s/%s", to, e->d_name);
                if (linkat(dirfd(d), e->d_name, AT_FDCWD, file, 0) < 0)
                        r = -errno;
        }
        closedir(d);
        return r;
}

int ap_model_write(const struct ap_model *m, const char *ds_dir)
{
        char models[4096], tmp[4200], final[4200];
        _cleanup_close_ int dfd = -EBADF;
        int r;

        if (!m || !ds_dir || !m->name[0] || strchr(m->name, '/') || m->name[0] == '.')
                return -EINVAL;
        snprintf(models, sizeof(models), "%s/models", ds_dir);
        if (mkdir(models, 0755) < 0 && errno != EEXIST)
                return -errno;
        snprintf(final, sizeof(final), "%s/%s", models, m->name);
        snprintf(tmp, sizeof(tmp), "%s/.%s.tmp", models, m->name);
        ap_remove_tree(tmp); /* left by an interrupted write */
        if (mkdir(tmp, 0755) < 0)
                return -errno;
        dfd = open(tmp, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
        r = dfd < 0 ? -errno : put_model(dfd, m);
        if (r == 0)
                r = keep_brdf(final, tmp);
        if (r == 0)
                r = ap_io_install_dir(tmp, final);
        if (r < 0)
                ap_remove_tree(tmp);
        return r;
}

/* ---- reading ---- */

int ap_io_bad(const struct ap_io_rd *rd, const char *file, const char *fmt, ...)
{
        char msg[512];
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(msg, sizeof(msg), fmt, ap);
        va_end(ap);
        snprintf(rd->err, rd->errlen, "%s/%s: %s", rd->dir, file, msg);
        return -EBADMSG;
}

int ap_io_slurp(const struct ap_io_rd *rd, const char *file, size_t want, void **buf, size_t *len)
{
        char path[4400];
        int r;

        snprintf(path, sizeof(path), "%s/%s", rd->dir, file);
        r = gn_read_file_at(AT_FDCWD, path, (size_t)1 << 32, buf, len);
        if (r < 0) {
                snprintf(rd->err, rd->errlen, "%s: %s", path, strerror(-r));
                return r == -ENOENT ? -EBADMSG : r;
        }
        if (want && *len != want)
                return ap_io_bad(rd, file, "%zu bytes, expected %zu", *len, want);
        return 0;
}

int ap_io_get_vec(const struct ap_io_rd *rd, json_t *o, const char *key, double *v, size_t n,
                  const char *where)
{
        json_t *a = json_object_get(o, key);

        if (!json_is_array(a) || json_array_size(a) != n)
                return ap_io_bad(rd, rd->json ? rd->json : "model.json",
                                 "%s: '%s' is not an array of %zu numbers", where, key, n);
        for (size_t i = 0; i < n; i++) {
                if (!json_is_number(json_array_get(a, i)))
                        return ap_io_bad(rd, rd->json ? rd->json : "model.json",
                                         "%s: '%s'[%zu] is not a number", where, key, i);
                v[i] = json_number_value(json_array_get(a, i));
        }
        return 0;
}

int ap_io_get_camera(const struct ap_io_rd *rd, json_t *o, struct ap_camera *c, const char *where)
{
        json_error_t e;
        int r;

        if (json_unpack_ex(o, &e, 0, "{s:i,s:i,s:F,s:F,s:F,s:F}", "width", &c->width, "height",
                           &c->height, "fx", &c->fx, "fy", &c->fy, "cx", &c->cx, "cy", &c->cy) < 0)
                return ap_io_bad(rd, rd->json ? rd->json : "model.json", "%s: geometry: %s", where,
                                 e.text);
        if (c->width <= 0 || c->height <= 0 || c->width > 16384 || c->height > 16384)
                return ap_io_bad(rd, rd->json ? rd->json : "model.json",
                                 "%s: geometry: size %dx%d out of range", where, c->width,
                                 c->height);
        r = ap_io_get_vec(rd, o, "dist", c->dist, 5, where);
        if (r == 0)
                r = ap_io_get_vec(rd, o, "R", c->R, 9, where);
        if (r == 0)
                r = ap_io_get_vec(rd, o, "t", c->t, 3, where);
        return r;
}

static int read_png(const struct ap_io_rd *rd, const char *file, const struct ap_view *v,
                    uint16_t *u16, uint8_t *u8)
{
        _cleanup_free_ void *buf = NULL;
        char msg[256];
        size_t len;
        int r = ap_io_slurp(rd, file, 0, &buf, &len);

        if (r < 0)
                return r;
        r = ap_png_decode(buf, len, v->cam.width, v->cam.height, u16, u8, msg, sizeof(msg));
        return r == -EBADMSG ? ap_io_bad(rd, file, "%s", msg) : r;
}

/* Reads view i's weight images and mask. */
static int read_view_images(const struct ap_io_rd *rd, struct ap_view *v, size_t i, int K)
{
        size_t n = (size_t)v->cam.width * v->cam.height;
        _cleanup_free_ uint16_t *q = malloc(n * 4 * sizeof(uint16_t));
        char file[64];
        int r;

        if (!q)
                return -ENOMEM;
        snprintf(file, sizeof(file), "views/%03zu_mask.png", i);
        r = read_png(rd, file, v, NULL, v->mask);
        for (size_t p = 0; r == 0 && p < n; p++)
                v->mask[p] = v->mask[p] >= 128;
        for (int g = 0; r == 0 && 4 * g < K; g++) {
                snprintf(file, sizeof(file), "views/%03zu_w%d.png", i, g);
                r = read_png(rd, file, v, q, NULL);
                for (size_t p = 0; r == 0 && p < n; p++) /* 0 outside the mask */
                        for (int c = 0; c < 4 && 4 * g + c < K && v->mask[p]; c++)
                                v->weights[p * K + 4 * g + c] =
                                        q[p * 4 + c] * v->scale[4 * g + c] + v->offset[4 * g + c];
        }
        return r;
}

static double angle_of(json_t *o, const char *key)
{
        json_t *v = json_object_get(o, key);

        return json_is_number(v) ? json_number_value(v) : NAN;
}

static int read_view(const struct ap_io_rd *rd, json_t *o, struct ap_model *m, size_t i)
{
        struct ap_view *v = &m->views[i];
        double q[2 * AP_K_MAX];
        const char *cam = NULL;
        char where[32];
        int r;

        snprintf(where, sizeof(where), "views[%zu]", i);
        if (json_unpack(o, "{s:s}", "camera", &cam) < 0 || strlen(cam) >= sizeof(v->camera))
                return ap_io_bad(rd, "model.json", "%s: no camera name", where);
        snprintf(v->camera, sizeof(v->camera), "%s", cam);
        v->turntable_deg = angle_of(o, "turntable_deg");
        v->camera_arm_deg = angle_of(o, "camera_arm_deg");
        r = ap_io_get_vec(rd, o, "dir", v->dir, 3, where);
        if (r == 0)
                r = ap_io_get_camera(rd, json_object_get(o, "geometry"), &v->cam, where);
        if (r == 0)
                r = ap_io_get_vec(rd, o, "scale", q, m->k, where);
        if (r == 0)
                r = ap_io_get_vec(rd, o, "offset", q + AP_K_MAX, m->k, where);
        for (int k = 0; r == 0 && k < m->k; k++) {
                v->scale[k] = (float)q[k];
                v->offset[k] = (float)q[AP_K_MAX + k];
        }
        if (r == 0)
                r = ap_view_alloc(v, m->k);
        return r < 0 ? r : read_view_images(rd, v, i, m->k);
}

static int read_basis(const struct ap_io_rd *rd, struct ap_model *m)
{
        size_t n3 = 3 * (size_t)m->n_coef, want = n3 * (m->k + 1) * sizeof(float), len;
        _cleanup_free_ void *buf = NULL;
        int r = ap_io_slurp(rd, "basis.f32", 0, &buf, &len);

        if (r < 0)
                return r;
        if (len != want)
                return ap_io_bad(rd, "basis.f32", "%zu bytes, expected %zu ((K + 1) x 3M float32)",
                                 len, want);
        memcpy(m->mean, buf, n3 * sizeof(float));
        memcpy(m->basis, (float *)buf + n3, n3 * m->k * sizeof(float));
        return 0;
}

/* The header fields of model.json into a new model (views not read). */
static int read_header(const struct ap_io_rd *rd, json_t *doc, struct ap_model **ret)
{
        const char *fmt = "", *name = "", *notes = "", *reg = "";
        json_t *views = NULL;
        json_error_t e;
        int order, k, version, r;

        if (json_unpack_ex(doc, &e, 0, "{s:s,s:s,s:i,s:i,s:s,s:o}", "format", &fmt, "name", &name,
                           "order", &order, "components", &k, "notes", &notes, "views", &views) < 0)
                return ap_io_bad(rd, "model.json", "%s", e.text);
        if (sscanf(fmt, "gonio-appearance %d", &version) == 1 && version > MODEL_VERSION)
                return ap_io_bad(rd, "model.json",
                                 "format '%s' is newer than this gonio reads ('%s'): update gonio",
                                 fmt, MODEL_FORMAT);
        if (strcmp(fmt, MODEL_FORMAT) != 0)
                return ap_io_bad(rd, "model.json", "format '%s', expected '%s'", fmt, MODEL_FORMAT);
        if (order < 1 || order > AP_ORDER_MAX || k < 1 || k > AP_K_MAX)
                return ap_io_bad(rd, "model.json", "order %d or components %d out of range", order,
                                 k);
        if (!json_is_array(views) || json_array_size(views) == 0)
                return ap_io_bad(rd, "model.json", "'views' is not a non-empty array");
        r = ap_model_new(order, k, json_array_size(views), ret);
        if (r < 0)
                return r;
        snprintf((*ret)->name, sizeof((*ret)->name), "%s", name);
        snprintf((*ret)->notes, sizeof((*ret)->notes), "%s", notes);
        json_unpack(doc, "{s?{s?F,s?F},s?{s?s,s?F,s?F,s?F,s?F}}", "light", "distance_mm",
                    &(*ret)->light_distance_mm, "intensity", &(*ret)->light_intensity, "fit",
                    "regularisation", &reg, "parameter", &(*ret)->reg_param, "rms_sh",
                    &(*ret)->rms_sh, "rms_pca", &(*ret)->rms_pca, "seconds", &(*ret)->fit_seconds);
        snprintf((*ret)->reg, sizeof((*ret)->reg), "%s", reg);
        return 0;
}

int ap_model_read(const char *dir, struct ap_model **ret, char *err, size_t errlen)
{
        struct ap_io_rd rd = {dir, err, errlen};
        _cleanup_(json_decrefp) json_t *doc = NULL;
        _cleanup_free_ void *text = NULL;
        struct ap_model *m = NULL;
        json_error_t e;
        size_t len;
        int r;

        r = ap_io_slurp(&rd, "model.json", 0, &text, &len);
        if (r < 0)
                return r == -EBADMSG ? -ENOENT : r;
        doc = json_loadb(text, len, 0, &e);
        if (!doc)
                return ap_io_bad(&rd, "model.json", "line %d: %s%s", e.line, e.text,
                                 e.position >= (int)len ? " (the file is cut short)" : "");
        r = read_header(&rd, doc, &m);
        for (size_t i = 0; r == 0 && i < m->n_views; i++)
                r = read_view(&rd, json_array_get(json_object_get(doc, "views"), i), m, i);
        if (r == 0)
                r = read_basis(&rd, m);
        if (r < 0) {
                ap_model_free(m);
                return r;
        }
        *ret = m;
        return 0;
}
