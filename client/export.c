/* export.c - gonioctl dataset export (client/export.h): the command line parsed into
 * appearance/export.h's options, ap_export run, its result or error printed. */
#include <errno.h>
#include <getopt.h>
#include <stdio.h>
#include <string.h>

#include "appearance/export.h"
#include "client/cmd.h"
#include "client/export.h"
#include "drivers/registry.h"

#define WHAT "dataset export"

/* What the command line asks. */
struct export_cli {
        struct ap_export_opts o;
        const char *dataset, *format, *dir;
};

/* Parses words[0 .. n) ("export" first) into e. Returns 0 or -EINVAL (message printed). */
static int parse_export(int n, char **words, struct export_cli *e)
{
        static const struct option opts[] = {
                {"format", required_argument, NULL, 'f'},
                {"output", required_argument, NULL, 'o'},
                {"model", required_argument, NULL, 'm'},
                {"calibration", required_argument, NULL, 'c'},
                {},
        };
        int c;

        e->o.backends = registry_backends;
        optind = 0; /* glibc: a full reset, words is not the process's argv */
        opterr = 0;
        while ((c = getopt_long(n, words, "o:", opts, NULL)) != -1) {
                if (c == 'f')
                        e->format = optarg;
                else if (c == 'o')
                        e->dir = optarg;
                else if (c == 'm')
                        e->o.model = optarg;
                else if (c == 'c')
                        e->o.calibration = optarg;
                else
                        return args_usage_error(WHAT, "unknown option or missing value '%s'",
                                                words[optind - 1]);
        }
        if (optind != n - 1 || !e->format || !e->dir)
                return args_usage_error(WHAT, "needs DATASET, --format and -o (usage: dataset "
                                              "export DATASET --format F -o DIR)");
        e->dataset = words[optind];
        return 0;
}

int export_command(const struct args *a, struct out *o, json_t **ret)
{
        struct export_cli e = {0};
        char err[1024] = "", notes[1024] = "";
        int r;

        if (parse_export(a->nwords - 1, a->words + 1, &e) < 0)
                return EXIT_USAGE;
        e.o.notes = notes;
        e.o.notes_len = sizeof(notes);
        r = ap_export(e.dataset, e.format, e.dir, &e.o, err, sizeof(err));
        if (r < 0) {
                out_error(o, WHAT, "%s", err[0] ? err : strerror(-r));
                return cmd_exit_for_errno(r);
        }
        *ret = json_pack("{s:s,s:s,s:s,s:s}", "dataset", e.dataset, "format", e.format, "dir",
                         e.dir, "notes", notes);
        return *ret ? EXIT_OK : EXIT_PROTOCOL;
}

void export_print(json_t *res)
{
        printf("%s: %s written into %s\n", json_string_value(json_object_get(res, "dataset")),
               json_string_value(json_object_get(res, "format")),
               json_string_value(json_object_get(res, "dir")));
        if (*json_string_value(json_object_get(res, "notes")))
                printf("notes: %s\n", json_string_value(json_object_get(res, "notes")));
}
