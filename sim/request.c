/* request.c - fields and error replies of gonio-sim's socket requests (see request.h). */
#include <errno.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "sim/request.h"

int sim_req_fail(struct sim_req *rq, int err, const char *fmt, ...)
{
        va_list ap;

        va_start(ap, fmt);
        vsnprintf(rq->msg, sizeof rq->msg, fmt, ap);
        va_end(ap);
        return -err;
}

int sim_req_int(struct sim_req *rq, const char *key, long min, long max, long *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_integer(v) || json_integer_value(v) < min || json_integer_value(v) > max)
                return sim_req_fail(rq, EINVAL, "'%s' must be an integer in [%ld, %ld]", key, min,
                                    max);
        *out = (long)json_integer_value(v);
        return 1;
}

int sim_req_num(struct sim_req *rq, const char *key, double min, double max, double *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_number(v) || json_number_value(v) < min || json_number_value(v) > max)
                return sim_req_fail(rq, EINVAL, "'%s' must be a number in [%g, %g]", key, min, max);
        *out = json_number_value(v);
        return 1;
}

int sim_req_bool(struct sim_req *rq, const char *key, bool *out)
{
        json_t *v = json_object_get(rq->req, key);

        if (!v)
                return 0;
        if (!json_is_boolean(v))
                return sim_req_fail(rq, EINVAL, "'%s' must be true or false", key);
        *out = json_is_true(v);
        return 1;
}

int sim_req_camera(struct sim_req *rq, const struct rig_config *rc, int *ci)
{
        const char *name = json_string_value(json_object_get(rq->req, "camera"));

        if (!name)
                return sim_req_fail(rq, EINVAL, "'camera' must be a camera name");
        for (size_t i = 0; i < rc->n_cameras; i++)
                if (strcmp(rc->cameras[i].name, name) == 0) {
                        *ci = (int)i;
                        return 0;
                }
        return sim_req_fail(rq, ENOENT, "no camera '%s' in the rig", name);
}

json_t *sim_req_error_json(const struct sim_req *rq, int r)
{
        const char *name = strerrorname_np(-r);

        return json_pack("{s:b, s:s, s:s}", "ok", 0, "error", name ? name : "EIO", "message",
                         rq->msg[0] ? rq->msg : strerror(-r));
}
