/* test-datasets.c - the dataset.* methods through goniod as gonioctl calls them:
 * create, open, close, list and info of several datasets, their errors, and a dataset
 * of schema 1 opened (and migrated) by the daemon.
 *
 * goniod marks its loop thread with ds_forbid_thread() while it serves, and this build
 * has assertions on, so any dataset I/O these methods did on the loop would abort
 * goniod: the next call would then fail. That is how this test proves they run on the
 * dataset worker (no timing involved). */
#include <errno.h>
#include <stdio.h>
#include <string.h>

#include "common/frame.h"
#include "dataset/ds.h"
#include "tests/dataset/ds-util.h"
#include "harness.h"
#include "tests/test.h"

static json_t *list_names(struct rigenv *e)
{
        json_t *r = ctl_ok(e, "dataset", "list", NULL);
        json_t *names = json_object();
        size_t i;
        json_t *v;

        json_array_foreach(json_object_get(r, "datasets"), i, v)
        {
                CHECK_STR(json_string_value(json_object_get(v, "rig")), "e2e");
                CHECK(strlen(json_string_value(json_object_get(v, "created"))) == 20);
                json_object_set(names, json_string_value(json_object_get(v, "name")),
                                json_object_get(v, "count"));
        }
        json_decref(r);
        return names;
}

/* The name of the open dataset in status, or NULL. */
static const char *status_dataset(struct rigenv *e, char *buf, size_t len)
{
        json_t *r = ctl_ok(e, "status", NULL), *d = json_object_get(r, "dataset");
        bool open = json_is_object(d);

        if (open)
                snprintf(buf, len, "%s", json_string_value(json_object_get(d, "name")));
        json_decref(r);
        return open ? buf : NULL;
}

static void test_lifecycle(struct rigenv *e)
{
        char buf[64];
        json_t *r, *names;

        names = list_names(e);
        CHECK_INT(json_object_size(names), 0);
        json_decref(names);
        json_decref(ctl_ok(e, "dataset", "create", "a", NULL));
        json_decref(ctl_ok(e, "dataset", "create", "b", NULL));
        CHECK_STR(status_dataset(e, buf, sizeof(buf)), "b");
        CHECK_INT(ctl(e, NULL, "dataset", "create", "a", NULL), 7); /* exists */
        CHECK_INT(ctl(e, NULL, "dataset", "open", "nope", NULL), 6);
        CHECK_STR(status_dataset(e, buf, sizeof(buf)), "b"); /* a failed open keeps it */
        json_decref(ctl_ok(e, "dataset", "close", NULL));
        CHECK(status_dataset(e, buf, sizeof(buf)) == NULL);
        json_decref(ctl_ok(e, "dataset", "close", NULL)); /* none open: fine */
        CHECK_INT(ctl(e, NULL, "dataset", "info", NULL), 6);

        r = ctl_ok(e, "dataset", "open", "a", NULL);
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 0);
        json_decref(r);
        json_decref(ctl_ok(e, "capture", "--camera", "cam0", NULL));
        r = ctl_ok(e, "dataset", "info", NULL);
        CHECK_STR(json_string_value(json_object_get(r, "name")), "a");
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 1);
        CHECK_INT(json_array_size(json_object_get(r, "captures")), 1);
        CHECK_STR(json_string_value(json_array_get(json_object_get(r, "cameras"), 0)), "cam0");
        json_decref(r);
        r = ctl_ok(e, "dataset", "open", "a", NULL); /* the open one, after a store: reopened */
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 1);
        json_decref(r);
        r = ctl_ok(e, "dataset", "info", "b", NULL);
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 0);
        json_decref(r);

        names = list_names(e);
        CHECK_INT(json_object_size(names), 2);
        CHECK_INT(json_integer_value(json_object_get(names, "a")), 1);
        CHECK_INT(json_integer_value(json_object_get(names, "b")), 0);
        json_decref(names);
}

/* A dataset written by the first schema (NOT NULL angles, no lamp_bits, no names). */
static void make_schema1(struct rigenv *e, const char *name)
{
        char path[400];
        struct ds *d = NULL;

        snprintf(path, sizeof(path), "%s/%s", e->data, name);
        CHECK_INT(ds_create(path, name, "rig: e2e\n", &d), 0);
        ds_close(d);
        tu_make_schema1(path, NULL);
}

static void test_old_schema(struct rigenv *e)
{
        json_t *r;

        make_schema1(e, "old");
        r = ctl_ok(e, "dataset", "open", "old", NULL);
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 0);
        json_decref(r);
        r = ctl_ok(e, "capture", NULL);
        CHECK_INT(json_array_size(json_object_get(r, "captures")), 2);
        json_decref(r);
        r = ctl_ok(e, "dataset", "info", "old", NULL);
        CHECK_INT(json_integer_value(json_object_get(r, "count")), 2);
        json_decref(r);
        json_decref(ctl_ok(e, "dataset", "close", NULL));
        json_decref(ctl_ok(e, "status", NULL)); /* goniod is still alive */
}

int main(int argc, char **argv)
{
        struct rigenv e;

        CHECK(argc == 4);
        rigenv_start(&e, argv, 10);
        test_lifecycle(&e);
        test_old_schema(&e);
        rigenv_stop(&e);
        return 0;
}
