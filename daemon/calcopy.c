/* calcopy.c - the rig's calibration file in goniod (see calcopy.h). */
#include <errno.h>
#include <fcntl.h>
#include <limits.h>
#include <stdlib.h>
#include <string.h>

#include "calcopy.h"
#include "common/cleanup.h"
#include "common/fileio.h"
#include "common/log.h"
#include "common/sha256.h"
#include "common/yconf.h"
#include "datasets.h"
#include "manager.h"

#define CALCOPY_FORMAT "gonio-calibration 1" /* calib/calfile.h CAL_FILE_FORMAT */
#define CALCOPY_MAX    (4 << 20)             /* bytes of a calibration file */

/* Why gn_read_file_at or gn_write_atomic failed with r. */
static const char *io_error(int r)
{
        return r == -EBADMSG ? "not a regular file" : strerror(-r);
}

/* "ok", or why the file at path cannot be used, with message. */
static const char *check_file(const char *path, char *msg, size_t len)
{
        _cleanup_free_ void *text = NULL;
        struct yconf yc;
        char format[64] = "";
        size_t n;
        int r = gn_read_file_at(AT_FDCWD, path, CALCOPY_MAX, &text, &n);

        if (r == -ENOENT) {
                snprintf(msg, len, "%s does not exist (yet): calibrate with gonioctl calibrate",
                         path);
                return "missing";
        }
        if (r < 0) {
                snprintf(msg, len, "cannot read %s: %s", path, io_error(r));
                return "unreadable";
        }
        r = yconf_open_string(&yc, path, text, msg, len);
        if (r == 0 && yconf_str(&yc, yconf_root(&yc), "format", format, sizeof(format)) >= 0 &&
            strcmp(format, CALCOPY_FORMAT) != 0)
                snprintf(msg, len, "%s: not a calibration file (no 'format: " CALCOPY_FORMAT "')",
                         path);
        yconf_close(&yc);
        return r < 0 || strcmp(format, CALCOPY_FORMAT) != 0 ? "invalid" : "ok";
}

json_t *calcopy_check(const struct rig_config *rc)
{
        char msg[600] = "";
        const char *state =
                rc->calibration[0] ? check_file(rc->calibration, msg, sizeof(msg)) : "none";
        json_t *j = json_pack("{s:s?,s:s}", "path", rc->calibration[0] ? rc->calibration : NULL,
                              "state", state);
        char hex[GN_SHA256_HEX];

        if (j && strcmp(state, "ok") != 0 && msg[0])
                json_object_set_new(j, "message", json_string(msg));
        if (j && strcmp(state, "ok") == 0 && gn_sha256_file_at(AT_FDCWD, rc->calibration, hex) == 0)
                json_object_set_new(j, "sha256", json_string(hex));
        return j;
}

void calcopy_warn(const struct rig_config *rc)
{
        json_t *j = calcopy_check(rc);
        const char *msg = json_string_value(json_object_get(j, "message"));

        if (msg)
                log_warning("Calibration file of rig '%s': %s; datasets will not carry it",
                            rc->name, msg);
        json_decref(j);
}

int calcopy_into(const struct rig_config *rc, const char *ds_dir)
{
        _cleanup_(gn_sha256_freep) struct gn_sha256 *sha = NULL;
        char dest[PATH_MAX], hex[GN_SHA256_HEX] = "";
        _cleanup_free_ void *text = NULL;
        size_t len = 0;
        int r;

        if (!rc->calibration[0])
                return 0;
        if ((size_t)snprintf(dest, sizeof(dest), "%s/calibration.yaml", ds_dir) >= sizeof(dest))
                return -ENAMETOOLONG;
        r = gn_read_file_at(AT_FDCWD, rc->calibration, CALCOPY_MAX, &text, &len);
        if (r >= 0 && (r = gn_sha256_new(&sha)) >= 0 &&
            (r = gn_write_atomic(AT_FDCWD, dest, text, len, sha)) >= 0)
                (void)gn_sha256_final(sha, hex);
        if (r < 0) {
                log_warning("Cannot copy the calibration file %s into dataset %s: %s",
                            rc->calibration, ds_dir, io_error(r));
                return r;
        }
        log_info("Copied the calibration file %s (sha256 %s) into dataset %s", rc->calibration, hex,
                 ds_dir);
        return 0;
}

/* describe on the dataset worker. */
struct describe_job {
        const struct rig_config *rc;
        struct srv_req *req;
        json_t *d;
};

static int describe_run(void *userdata)
{
        struct describe_job *j = userdata;

        return json_object_set_new(j->d, "calibration", calcopy_check(j->rc)) < 0 ? -ENOMEM : 0;
}

static void describe_done(int result, void *userdata)
{
        struct describe_job *j = userdata;

        if (result < 0)
                srv_fail(j->req, result, "%s",
                         result == -ECANCELED ? "goniod is shutting down" : strerror(-result));
        else
                srv_reply(j->req, j->d);
        if (result < 0)
                json_decref(j->d);
        free(j);
}

int calcopy_describe(struct manager *m, struct srv_req *req, json_t *d)
{
        struct describe_job *j = calloc(1, sizeof(*j));
        int r;

        if (!j || !d) {
                free(j);
                json_decref(d);
                return -ENOMEM;
        }
        *j = (struct describe_job){.rc = m->rc, .req = req, .d = d};
        r = datasets_push(m, describe_run, describe_done, j);
        if (r < 0) {
                json_decref(d);
                free(j);
        }
        return r;
}
