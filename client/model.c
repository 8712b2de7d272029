/* model.c - gonioctl model fit DATASET [--name N] [--order P] [--components K] [--sample F]
 * [--reg tikhonov|tsvd] [--reg-param X] [--tile N] [--threads N] [--calibration FILE|nominal]
 * [--mesh FILE] [--force]: the appearance fit of a dataset (appearance/fit.h) written as
 * models/<name>/ of the dataset (appearance/model.h), without goniod; with --brdf [--texels N]
 * [--per-view] the BRDF fit instead (appearance/brdf_fit.h; per texel of the mesh, or per
 * pixel of each view where there is no mesh or --per-view asks) written as
 * models/<name>/brdf/; the summary as text or JSON (docs/appearance.md, "gonioctl model
 * fit"). */
#include <errno.h>
#include <getopt.h>
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "appearance/brdf_fit.h"
#include "appearance/fit.h"
#include "client/cmd.h"
#include "client/model.h"
#include "common/cleanup.h"
#include "dataset/ds.h"
#include "drivers/registry.h"
#include "common/sortx.h"

#define WHAT "model fit"

DEFINE_TRIVIAL_CLEANUP_FUNC(struct ds *, ds_close);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_model *, ap_model_free);
DEFINE_TRIVIAL_CLEANUP_FUNC(struct ap_brdf_model *, ap_brdf_model_free);

/* What the command line asks beyond the fit's options. */
struct fit_cli {
        struct ap_fit_opts o;
        const char *dataset;
        bool force;
        bool brdf;     /* --brdf: the BRDF fit */
        bool per_view; /* --per-view: of the view kind */
        long texels;   /* its --texels, 0: the default */
};

/* Stores option c's value v into f. Returns 0 or -EINVAL (message printed). */
static int set_opt(struct fit_cli *f, int c, const char *v)
{
        double x = 0;
        long n = 0;
        bool num = args_parse_double(v, &x) == 0, integer = args_parse_long(v, 1, 64, &n) == 0;

        switch (c) {
        case 'n':
                f->o.name = v;
                return 0;
        case 'c':
                f->o.calibration = v;
                return 0;
        case 'm':
                f->o.mesh = v;
                return 0;
        case 'P':
                f->o.order = (int)n;
                return integer && n <= AP_ORDER_MAX ? 0 : -EINVAL;
        case 'K':
                f->o.k = (int)n;
                return integer && n <= AP_K_MAX ? 0 : -EINVAL;
        case 's':
                f->o.sample = x;
                return num && x > 0 && x <= 1 ? 0 : -EINVAL;
        case 'x':
                f->o.reg_param = x;
                return num && x >= 0 ? 0 : -EINVAL;
        case 't':
                f->o.tile = (int)n;
                return integer ? 0 : -EINVAL;
        case 'j':
                f->o.threads = (int)n;
                return integer && n <= 16 ? 0 : -EINVAL;
        case 'T':
                return args_parse_long(v, 16, 1L << 26, &f->texels);
        case 'r':
                f->o.reg = strcmp(v, "tsvd") == 0 ? AP_REG_TSVD : AP_REG_TIKHONOV;
                return strcmp(v, "tsvd") == 0 || strcmp(v, "tikhonov") == 0 ? 0 : -EINVAL;
        }
        return -EINVAL;
}

/* Parses words[0 .. n) ("fit" first) into f. Returns 0 or -EINVAL (message printed). */
static int parse_fit(int n, char **words, struct fit_cli *f)
{
        static const struct option opts[] = {
                {"name", required_argument, NULL, 'n'},
                {"order", required_argument, NULL, 'P'},
                {"components", required_argument, NULL, 'K'},
                {"sample", required_argument, NULL, 's'},
                {"reg", required_argument, NULL, 'r'},
                {"reg-param", required_argument, NULL, 'x'},
                {"tile", required_argument, NULL, 't'},
                {"threads", required_argument, NULL, 'j'},
                {"calibration", required_argument, NULL, 'c'},
                {"mesh", required_argument, NULL, 'm'},
                {"force", no_argument, NULL, 'f'},
                {"brdf", no_argument, NULL, 'b'},
                {"texels", required_argument, NULL, 'T'},
                {"per-view", no_argument, NULL, 'V'},
                {},
        };
        int c, li = 0;

        ap_fit_opts_default(&f->o);
        f->o.backends = registry_backends;
        optind = 0; /* glibc: a full reset, words is not the process's argv */
        opterr = 0;
        while ((c = getopt_long(n, words, "", opts, &li)) != -1) {
                if (c == 'f' || c == 'b' || c == 'V')
                        *(c == 'f' ? &f->force : c == 'b' ? &f->brdf : &f->per_view) = true;
                else if (c == '?' || c == ':')
                        return args_usage_error(WHAT, "unknown option or missing value '%s'",
                                                words[optind - 1]);
                else if (set_opt(f, c, optarg) < 0)
                        return args_usage_error(WHAT, "invalid value '%s' of --%s", optarg,
                                                opts[li].name);
        }
        if (optind != n - 1)
                return args_usage_error(WHAT, "needs one DATASET (usage: model fit DATASET "
                                              "[--name N] [--order P] [--components K] ...)");
        if ((f->texels || f->per_view) && !f->brdf)
                return args_usage_error(WHAT, "--%s needs --brdf",
                                        f->texels ? "texels" : "per-view");
        f->dataset = words[optind];
        return 0;
}

/* The summary of model m written at dir. */
static json_t *summary_json(const struct ap_model *m, const char *dir)
{
        return json_pack("{s:s,s:s,s:i,s:i,s:I,s:s,s:f,s:f,s:f,s:f,s:s}", "model", dir, "name",
                         m->name, "order", m->order, "components", m->k, "views",
                         (json_int_t)m->n_views, "regularisation", m->reg, "parameter",
                         m->reg_param, "rms_sh", m->rms_sh, "rms_pca", m->rms_pca, "seconds",
                         m->fit_seconds, "notes", m->notes);
}

/* Adds the n texels x to the counts by outcome k (fitted, diffuse only, masked) and the
 * residuals of those not masked to rms[*nr ..]. */
static void brdf_count(const struct ap_brdf_texel *x, size_t n, size_t k[3], float *rms, size_t *nr)
{
        for (size_t i = 0; i < n; i++) {
                uint32_t fl = x[i].flags;
                k[fl & AP_BRDF_FITTED ? 0 : fl & AP_BRDF_DIFFUSE_ONLY ? 1 : 2]++;
                if (!(fl & AP_BRDF_MASKED))
                        rms[(*nr)++] = x[i].rms;
        }
}

/* The summary of BRDF model m written at dir: texels (or the views' pixels) by outcome, the
 * median rms. */
static json_t *brdf_summary_json(const struct ap_brdf_model *m, const char *dir)
{
        bool view = m->kind == AP_BRDF_KIND_VIEW;
        size_t n = view ? 0 : (size_t)m->atlas.width * m->atlas.height, k[3] = {0}, nr = 0;
        _cleanup_free_ float *rms = NULL;

        for (size_t i = 0; i < m->n_views; i++)
                n += (size_t)m->views[i].cam.width * m->views[i].cam.height;
        if (!(rms = malloc((n + 1) * sizeof(float))))
                return NULL;
        if (!view)
                brdf_count(m->texels, n, k, rms, &nr);
        for (size_t i = 0; i < m->n_views; i++)
                brdf_count(m->views[i].px, (size_t)m->views[i].cam.width * m->views[i].cam.height,
                           k, rms, &nr);
        qsort(rms, nr, sizeof(float), gn_cmp_float);
        return json_pack("{s:s,s:s,s:b,s:s,s:I,s:I,s:I,s:I,s:I,s:f,s:f,s:f,s:s}", "model", dir,
                         "name", m->name, "brdf", 1, "kind", view ? "view" : "texel", "views",
                         (json_int_t)m->n_views, "texels", (json_int_t)n, "fitted",
                         (json_int_t)k[0], "diffuse_only", (json_int_t)k[1], "masked",
                         (json_int_t)k[2], "median_rms", nr ? (double)rms[nr / 2] : 0.0, "response",
                         m->response, "seconds", m->fit_seconds, "notes", m->notes);
}

/* The BRDF fit of dataset d with f's options, written and summarised. */
static int model_fit_brdf(const struct fit_cli *f, struct ds *d, const char *dir, struct out *o,
                          json_t **ret)
{
        _cleanup_(ap_brdf_model_freep) struct ap_brdf_model *m = NULL;
        struct ap_brdf_fit_opts bo;
        char err[1024];
        int r;

        ap_brdf_fit_opts_default(&bo);
        bo.name = f->o.name, bo.threads = f->o.threads, bo.calibration = f->o.calibration;
        bo.backends = f->o.backends;
        if (f->texels)
                bo.texels = (size_t)f->texels;
        if (f->per_view)
                bo.kind = AP_BRDF_FIT_VIEW;
        if ((r = ap_brdf_fit(d, &bo, &m, err, sizeof(err))) < 0) {
                out_error(o, WHAT, "%s: %s", f->dataset, err);
                return cmd_exit_for_errno(r);
        }
        if ((r = ap_brdf_write(m, ds_path(d))) < 0) {
                out_error(o, WHAT, "cannot write %s: %s", dir, strerror(-r));
                return EXIT_STORAGE;
        }
        *ret = brdf_summary_json(m, dir);
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

/* Fits, writes and summarises the model of f's dataset. */
static int model_fit(const struct fit_cli *f, struct out *o, json_t **ret)
{
        _cleanup_(ds_closep) struct ds *d = NULL;
        _cleanup_(ap_model_freep) struct ap_model *m = NULL;
        char err[1024], dir[4200];
        int r;

        if ((r = ds_open(f->dataset, &d)) < 0) {
                out_error(o, WHAT, "cannot open dataset %s: %s", f->dataset, strerror(-r));
                return EXIT_INVALID;
        }
        snprintf(dir, sizeof(dir), "%s/models/%s%s", ds_path(d), f->o.name, f->brdf ? "/brdf" : "");
        if (!f->force && access(dir, F_OK) == 0) {
                out_error(o, WHAT, "%s exists (--force replaces it)", dir);
                return EXIT_INVALID;
        }
        if (f->brdf)
                return model_fit_brdf(f, d, dir, o, ret);
        if ((r = ap_fit(d, &f->o, &m, err, sizeof(err))) < 0) {
                out_error(o, WHAT, "%s: %s", f->dataset, err);
                return cmd_exit_for_errno(r);
        }
        if ((r = ap_model_write(m, ds_path(d))) < 0) {
                out_error(o, WHAT, "cannot write %s: %s", dir, strerror(-r));
                return EXIT_STORAGE;
        }
        *ret = summary_json(m, dir);
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

int model_command(const struct args *a, struct out *o, json_t **ret)
{
        char **words = a->words + 1;
        int n = a->nwords - 1;
        struct fit_cli f = {0};

        if (n >= 1 && strcmp(words[0], "render") == 0) /* prints its own result */
                return model_render_command(n, words);
        if (n >= 1 && (strcmp(words[0], "view") == 0 || strcmp(words[0], "export") == 0))
                return model_web_command(n, words);
        if (n < 1 || strcmp(words[0], "fit") != 0) {
                args_usage_error("model",
                                 n < 1 ? "missing subcommand (fit, render, view, export)"
                                       : "unknown subcommand '%s' (fit, render, view, export)",
                                 n < 1 ? "" : words[0]);
                return EXIT_USAGE;
        }
        if (parse_fit(n, words, &f) < 0)
                return EXIT_USAGE;
        return model_fit(&f, o, ret);
}

/* The SH model's summary lines. */
static void sh_print(json_t *res)
{
        printf("model %s: order %d, %d components, %d views, %s %g\n",
               json_string_value(json_object_get(res, "model")),
               (int)json_integer_value(json_object_get(res, "order")),
               (int)json_integer_value(json_object_get(res, "components")),
               (int)json_integer_value(json_object_get(res, "views")),
               json_string_value(json_object_get(res, "regularisation")),
               json_real_value(json_object_get(res, "parameter")));
        printf("residual RMS: SH fit %.5f, PCA %.5f; %.2f s\n",
               json_real_value(json_object_get(res, "rms_sh")),
               json_real_value(json_object_get(res, "rms_pca")),
               json_real_value(json_object_get(res, "seconds")));
}

void model_print(json_t *res)
{
        const char *notes = json_string_value(json_object_get(res, "notes"));

        if (!res) /* model render: printed already */
                return;
        if (json_is_true(json_object_get(res, "brdf"))) {
                bool view = !strcmp(json_string_value(json_object_get(res, "kind")), "view");
                printf("BRDF model %s: %lld %s%s: %lld fitted, %lld diffuse only, %lld masked\n",
                       json_string_value(json_object_get(res, "model")),
                       (long long)json_integer_value(json_object_get(res, "texels")),
                       view ? "pixels of the views" : "texels", view ? " (no mesh)" : "",
                       (long long)json_integer_value(json_object_get(res, "fitted")),
                       (long long)json_integer_value(json_object_get(res, "diffuse_only")),
                       (long long)json_integer_value(json_object_get(res, "masked")));
                printf("median residual RMS %.5f; %.2f s\n",
                       json_real_value(json_object_get(res, "median_rms")),
                       json_real_value(json_object_get(res, "seconds")));
        } else {
                sh_print(res);
        }
        if (notes && *notes)
                printf("notes: %s\n", notes);
}
