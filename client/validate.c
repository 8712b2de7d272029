/* validate.c - gonioctl validate: a rig or session file checked by the loaders goniod runs,
 * here, so an operator finds "FILE:LINE: key 'k': reason" before starting anything. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "client/cmd.h"
#include "client/validate.h"
#include "common/cleanup.h"
#include "common/rigconf.h"
#include "common/sessconf.h"
#include "common/yconf.h"
#include "drivers/registry.h"

#define ERR_MAX 512

/* True when the YAML file at path reads as a session file: a mapping with `dataset` or
 * `sweep`. A file that does not parse is taken as a rig file; its loader says why. */
static bool is_session_file(const char *path)
{
        struct yconf yc = {};
        char err[ERR_MAX];
        struct fy_node *root;
        bool session;

        if (yconf_open(&yc, path, err, sizeof(err)) < 0)
                return false;
        root = yconf_root(&yc);
        session = yconf_get(root, "dataset") || yconf_get(root, "sweep");
        yconf_close(&yc);
        return session;
}

/* {kind, file, line, key, reason} from a loader's "FILE:LINE: key 'k': reason"; kind only
 * for other messages ("PATH: No such file or directory"). */
static json_t *error_detail(const char *kind, const char *err)
{
        const char *k = strstr(err, ": key '"), *kend = k ? strstr(k + 7, "': ") : NULL;
        const char *colon = k ? memrchr(err, ':', (size_t)(k - err)) : NULL;
        json_t *d = json_pack("{s:s}", "kind", kind);

        if (!d || !kend || !colon)
                return d;
        if (json_object_set_new(d, "file", json_stringn(err, (size_t)(colon - err))) < 0 ||
            json_object_set_new(d, "line", json_integer(strtol(colon + 1, NULL, 10))) < 0 ||
            json_object_set_new(d, "key", json_stringn(k + 7, (size_t)(kend - k - 7))) < 0 ||
            json_object_set_new(d, "reason", json_string(kend + 3)) < 0) {
                json_decref(d);
                return NULL;
        }
        return d;
}

/* Prints a loader's error and returns EXIT_INVALID (EXIT_STORAGE for an unreadable file other
 * than a missing one). */
static int invalid(struct out *o, const char *kind, int r, const char *err)
{
        out_error(o, NULL, "%s", err[0] ? err : strerror(-r));
        json_decref(o->error_detail);
        o->error_detail = error_detail(kind, err);
        return cmd_exit_for_errno(r);
}

static json_t *rig_summary(const char *path, const struct rig_config *rc)
{
        return json_pack("{s:s,s:s,s:b,s:s,s:i,s:i,s:i,s:i,s:i}", "file", path, "kind", "rig",
                         "valid", 1, "rig", rc->name, "buses", (int)rc->n_buses, "axes",
                         (int)rc->n_axes, "lamps", (int)rc->n_lamps, "lasers", (int)rc->n_lasers,
                         "cameras", (int)rc->n_cameras);
}

static int validate_session(const char *path, const char *rig, struct out *o, json_t **ret)
{
        struct rig_config *rc = NULL;
        struct session_conf *sc = NULL;
        char err[ERR_MAX] = "";
        int r = rigconf_load(rig, registry_backends, &rc, err, sizeof(err));

        if (r < 0)
                return invalid(o, "rig", r, err);
        r = sessconf_load(path, rc, &sc, err, sizeof(err));
        if (r < 0) {
                rigconf_free(rc);
                return invalid(o, "session", r, err);
        }
        *ret = json_pack("{s:s,s:s,s:b,s:s,s:s,s:s,s:s,s:i,s:i,s:i}", "file", path, "kind",
                         "session", "valid", 1, "name", sc->name, "dataset", sc->dataset, "rig",
                         rc->name, "rig_file", rig, "cameras", __builtin_popcount(sc->cameras),
                         "lamps", __builtin_popcount(sc->lamps), "brackets", (int)sc->n_brackets);
        sessconf_free(sc);
        rigconf_free(rc);
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

int validate_command(const struct args *a, struct out *o, json_t **ret)
{
        const char *path = a->words[1];
        struct rig_config *rc = NULL;
        char err[ERR_MAX] = "";
        int r;

        if (a->rig)
                return validate_session(path, a->rig, o, ret);
        if (is_session_file(path)) {
                args_usage_error("validate",
                                 "%s is a session file: give the rig file it runs on with --rig",
                                 path);
                return EXIT_USAGE;
        }
        r = rigconf_load(path, registry_backends, &rc, err, sizeof(err));
        if (r < 0)
                return invalid(o, "rig", r, err);
        *ret = rig_summary(path, rc);
        rigconf_free(rc);
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

static long long count(json_t *r, const char *key)
{
        return (long long)json_integer_value(json_object_get(r, key));
}

void validate_print(json_t *r)
{
        const char *kind = json_string_value(json_object_get(r, "kind")) ?: "";
        const char *file = json_string_value(json_object_get(r, "file")) ?: "";
        const char *rig = json_string_value(json_object_get(r, "rig")) ?: "";

        if (strcmp(kind, "session") == 0)
                printf("%s: valid session file (session %s into dataset %s on rig %s: %lld "
                       "cameras, %lld lamps, %lld brackets)\n",
                       file, json_string_value(json_object_get(r, "name")) ?: "",
                       json_string_value(json_object_get(r, "dataset")) ?: "", rig,
                       count(r, "cameras"), count(r, "lamps"), count(r, "brackets"));
        else
                printf("%s: valid rig file (rig %s: %lld buses, %lld axes, %lld lamps, %lld "
                       "lasers, %lld cameras)\n",
                       file, rig, count(r, "buses"), count(r, "axes"), count(r, "lamps"),
                       count(r, "lasers"), count(r, "cameras"));
}
