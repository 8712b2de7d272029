/* test-opcli.c - the operator commands of gonioctl that need no goniod, run as binaries:
 * validate on the example rig and session files and on broken variants of them (each class
 * of loader error, with its FILE:LINE: key and the --json error object), --version of every
 * program, COMMAND --help for every command of the usage, and usage and connection errors as
 * JSON objects under --json.
 * Usage: test-opcli GONIOCTL GONIOD GONIO_SIM SOURCE_ROOT VERSION CASE */
#include <fcntl.h>
#include <spawn.h>
#include <stdbool.h>
#include <sys/stat.h>

#include <jansson.h>

#include "tests/test.h"

static const char *gonioctl, *goniod, *gonio_sim, *srcdir, *version;
static char tmpdir[64];

/* The whole file at path, malloc'ed. */
static char *slurp(const char *path)
{
        FILE *f = fopen(path, "re");
        char *s = calloc(1, 1 << 20);

        CHECK(f && s);
        CHECK(fread(s, 1, (1 << 20) - 1, f) < (1 << 20) - 1);
        fclose(f);
        return s;
}

/* Runs argv (NULL-terminated), its stdout and stderr into *out and *err (malloc'ed). Returns
 * its exit status. */
static int run(const char *const *argv, char **out, char **err)
{
        char o[96], e[96];
        posix_spawn_file_actions_t fa;
        extern char **environ;
        int status;
        pid_t pid;

        snprintf(o, sizeof(o), "%s/out", tmpdir);
        snprintf(e, sizeof(e), "%s/err", tmpdir);
        CHECK_INT(posix_spawn_file_actions_init(&fa), 0);
        CHECK_INT(posix_spawn_file_actions_addopen(&fa, 1, o, O_WRONLY | O_CREAT | O_TRUNC, 0600),
                  0);
        CHECK_INT(posix_spawn_file_actions_addopen(&fa, 2, e, O_WRONLY | O_CREAT | O_TRUNC, 0600),
                  0);
        CHECK_INT(posix_spawn(&pid, argv[0], &fa, NULL, (char **)argv, environ), 0);
        posix_spawn_file_actions_destroy(&fa);
        CHECK_INT(waitpid(pid, &status, 0), pid);
        CHECK(WIFEXITED(status));
        *out = slurp(o);
        *err = slurp(e);
        return WEXITSTATUS(status);
}

/* The one JSON object on out (a single line). */
static json_t *parse_line(const char *out)
{
        json_error_t jerr;
        json_t *j = json_loads(out, 0, &jerr);

        if (!j)
                fprintf(stderr, "not JSON (%s): %s\n", jerr.text, out);
        CHECK(json_is_object(j));
        CHECK(strchr(out, '\n') == out + strlen(out) - 1);
        return j;
}

/* Runs gonioctl with args (NULL-terminated) under --json, checks the exit code, and checks
 * stdout is {"error":{"code":code,"exit":want,"message":...}}; returns the error object. */
static json_t *json_error(int want, const char *code, const char *const *args)
{
        const char *argv[16] = {gonioctl, "--json"};
        char *out, *err;
        json_t *j, *e;
        int n = 2;

        for (; *args; args++)
                argv[n++] = *args;
        CHECK_INT(run(argv, &out, &err), want);
        j = parse_line(out);
        e = json_object_get(j, "error");
        CHECK_STR(json_string_value(json_object_get(e, "code")), code);
        CHECK_INT(json_integer_value(json_object_get(e, "exit")), want);
        CHECK(json_string_length(json_object_get(e, "message")) > 0);
        CHECK(err[0]); /* the message for people is still on stderr */
        json_incref(e);
        json_decref(j);
        free(out);
        free(err);
        return e;
}

static void path_of(char *buf, size_t n, const char *rel)
{
        snprintf(buf, n, "%s/%s", srcdir, rel);
}

static void validate_examples(void)
{
        static const char *const rigs[] = {"ciclop", "lab", "paper", "sim"};
        static const char *const sessions[] = {"demo", "demo-relight", "paper"};
        char rig[512], path[512], *out, *err;

        for (size_t i = 0; i < sizeof(rigs) / sizeof(rigs[0]); i++) {
                char want[600];

                snprintf(path, sizeof(path), "%s/examples/rigs/%s.yaml", srcdir, rigs[i]);
                CHECK_INT(run((const char *[]){gonioctl, "validate", path, NULL}, &out, &err), 0);
                snprintf(want, sizeof(want), "%s: valid rig file (rig ", path);
                CHECK(strncmp(out, want, strlen(want)) == 0);
                CHECK_STR(err, "");
                free(out);
                free(err);
        }
        path_of(rig, sizeof(rig), "examples/rigs/sim.yaml");
        for (size_t i = 0; i < sizeof(sessions) / sizeof(sessions[0]); i++) {
                json_t *j;

                snprintf(path, sizeof(path), "%s/examples/sessions/%s.yaml", srcdir, sessions[i]);
                CHECK_INT(run((const char *[]){gonioctl, "--json", "validate", path, "--rig", rig,
                                               NULL},
                              &out, &err),
                          0);
                j = parse_line(out);
                CHECK(json_is_true(json_object_get(j, "valid")));
                CHECK_STR(json_string_value(json_object_get(j, "kind")), "session");
                CHECK_STR(json_string_value(json_object_get(j, "rig")), "sim-furukawa");
                json_decref(j);
                free(out);
                free(err);
        }
}

/* A broken variant of an example file: the first `from` replaced by `to`. */
struct broken {
        const char *name;
        bool session; /* of examples/sessions/demo.yaml (checked against sim.yaml), else of
                       * examples/rigs/sim.yaml */
        const char *from, *to;
        const char *at;     /* the error's line is the first holding this; NULL: not checked */
        const char *key;    /* the error's key; NULL: a message without one */
        const char *reason; /* in the message */
};

static const struct broken broken[] = {
        {"YAML syntax", false, "rig: sim-furukawa", "rig: [sim-furukawa", NULL, NULL,
         "YAML syntax error"},
        {"unknown key", false, "    settle_ms: 50\n", "    settle_ms: 50\n    frob: 1\n", "frob: 1",
         "frob", "unknown key"},
        {"out of range", false, "timeout_ms: 200", "timeout_ms: -5", "timeout_ms: -5", "timeout_ms",
         "out of range"},
        {"unknown bus", false, "bus: drives, unit: 1, profile", "bus: nowhere, unit: 1, profile",
         "bus: nowhere", "bus", "nowhere"},
        {"address clash", false, "unit: 2, profile: gonio-default }",
         "unit: 1, profile: gonio-default } # clash", "# clash", "unit", "both on unit 1"},
        {"missing key", false, "  - name: turntable\n    continuous: true", "  - continuous: true",
         "  - continuous: true", "name", "required key is missing"},
        {"bad limits", false, "limits: [-170, 170]", "limits: [170, -170]", "limits: [170, -170]",
         "limits", "min < max"},
        {"unknown camera", true, "cameras: [cam0, cam1]", "cameras: [cam0, cam9]", "cam9",
         "cameras", "unknown camera 'cam9'"},
        {"sweep beyond limits", true, "  light_arm: [0, 90]\n",
         "  light_arm: [0, 90]\n  camera_arm: [0, 200]\n", "camera_arm: [0, 200]",
         "sweep.camera_arm", "outside the soft limits"},
        {"session unknown key", true, "dark_frames: 1", "dark_frames: 1\nfrob: 2", "frob: 2",
         "frob", "unknown key"},
};

/* Writes the variant b into DIR/broken.yaml; *line gets the 1-based line of b->at. */
static void write_broken(const struct broken *b, char *path, size_t n, int *line)
{
        char src[512];
        char *text, *p, *q;
        FILE *f;

        path_of(src, sizeof(src),
                b->session ? "examples/sessions/demo.yaml" : "examples/rigs/sim.yaml");
        text = slurp(src);
        p = strstr(text, b->from);
        CHECK(p);
        snprintf(path, n, "%s/broken.yaml", tmpdir);
        f = fopen(path, "we");
        CHECK(f);
        fprintf(f, "%.*s%s%s", (int)(p - text), text, b->to, p + strlen(b->from));
        CHECK_INT(fclose(f), 0);
        free(text);
        text = slurp(path);
        q = b->at ? strstr(text, b->at) : NULL;
        *line = 1;
        for (p = text; q && p < q; p++)
                *line += *p == '\n';
        free(text);
}

static void check_broken(const struct broken *b)
{
        char path[128], rig[512], want[256], *out, *err;
        const char *argv[] = {gonioctl, "validate", path, "--rig", rig, NULL};
        json_t *e;
        int line;

        fprintf(stderr, "broken: %s\n", b->name);
        write_broken(b, path, sizeof(path), &line);
        path_of(rig, sizeof(rig), "examples/rigs/sim.yaml");
        if (!b->session)
                argv[3] = NULL;
        CHECK_INT(run(argv, &out, &err), 6);
        CHECK_STR(out, "");
        if (b->key)
                snprintf(want, sizeof(want), "%s:%d: key '%s': ", path, line, b->key);
        else
                snprintf(want, sizeof(want), "%s:", path);
        if (strncmp(err, want, strlen(want)) != 0)
                fprintf(stderr, "stderr '%s' does not start with '%s'\n", err, want);
        CHECK(strncmp(err, want, strlen(want)) == 0);
        CHECK_STR_CONTAINS(err, b->reason);
        free(out);
        free(err);

        e = json_error(6, "invalid", argv + 1);
        CHECK_STR(json_string_value(json_object_get(e, "kind")), b->session ? "session" : "rig");
        CHECK_STR_CONTAINS(json_string_value(json_object_get(e, "message")), b->reason);
        if (b->key) {
                CHECK_STR(json_string_value(json_object_get(e, "file")), path);
                CHECK_INT(json_integer_value(json_object_get(e, "line")), line);
                CHECK_STR(json_string_value(json_object_get(e, "key")), b->key);
        }
        json_decref(e);
}

static void validate_broken(void)
{
        char rig[512], session[512], *out, *err;
        json_t *e;

        for (size_t i = 0; i < sizeof(broken) / sizeof(broken[0]); i++)
                check_broken(&broken[i]);
        /* a session file without the rig it runs on: a usage error that says what it needs */
        path_of(session, sizeof(session), "examples/sessions/demo.yaml");
        CHECK_INT(run((const char *[]){gonioctl, "validate", session, NULL}, &out, &err), 2);
        CHECK_STR_CONTAINS(err, "is a session file: give the rig file it runs on with --rig");
        free(out);
        free(err);
        /* a missing file, and a session checked against a broken rig file */
        e = json_error(6, "invalid", (const char *[]){"validate", "/nonexistent.yaml", NULL});
        CHECK_STR_CONTAINS(json_string_value(json_object_get(e, "message")),
                           "/nonexistent.yaml: No such file or directory");
        json_decref(e);
        write_broken(&broken[1], rig, sizeof(rig), &(int){0});
        e = json_error(6, "invalid", (const char *[]){"validate", session, "--rig", rig, NULL});
        CHECK_STR(json_string_value(json_object_get(e, "kind")), "rig");
        CHECK_STR(json_string_value(json_object_get(e, "key")), "frob");
        json_decref(e);
}

static void versions(void)
{
        const char *progs[][2] = {
                {gonioctl, "gonioctl"}, {goniod, "goniod"}, {gonio_sim, "gonio-sim"}};

        for (size_t i = 0; i < 3; i++) {
                char want[128], *out, *err;

                CHECK_INT(run((const char *[]){progs[i][0], "--version", NULL}, &out, &err), 0);
                snprintf(want, sizeof(want), "%s %s", progs[i][1], version);
                CHECK(strncmp(out, want, strlen(want)) == 0);
                CHECK(out[strlen(want)] == '\n' || out[strlen(want)] == ' ');
                CHECK_STR(err, "");
                free(out);
                free(err);
        }
}

/* Runs gonioctl W1 [W2] --help for one line of the command list ("  dataset info [NAME]  ...").
 * Returns false for lines that are not commands. */
static bool help_of(const char *line)
{
        char w1[32] = "", w2[32] = "", want[96], *out, *err;
        const char *argv[] = {gonioctl, w1, w2, "--help", NULL};

        if (strncmp(line, "  ", 2) != 0 || line[2] == ' ' || /* a continued line */
            sscanf(line, "  %31s %31s", w1, w2) < 1 || w1[0] < 'a' || w1[0] > 'z')
                return false;
        if (strspn(w2, "abcdefghijklmnopqrstuvwxyz") != strlen(w2) || !w2[0])
                argv[2] = "--help", argv[3] = NULL;
        fprintf(stderr, "%s %s --help\n", w1, argv[3] ? w2 : "");
        CHECK_INT(run(argv, &out, &err), 0);
        snprintf(want, sizeof(want), "Usage: gonioctl [OPTIONS] %s", w1);
        if (strncmp(out, want, strlen(want)) != 0)
                fprintf(stderr, "%s %s --help: %s\n", w1, w2, out);
        CHECK(strncmp(out, want, strlen(want)) == 0);
        CHECK_STR(err, "");
        free(out);
        free(err);
        return true;
}

static void help(void)
{
        char *out, *err, *line, *save = NULL;
        int n = 0;

        CHECK_INT(run((const char *[]){gonioctl, "--help", NULL}, &out, &err), 0);
        line = strtok_r(strstr(out, "Commands:\n"), "\n", &save);
        while ((line = strtok_r(NULL, "\n", &save)) && strcmp(line, "Options:") != 0)
                n += help_of(line);
        CHECK(n >= 30);
        free(out);
        free(err);
        /* an option of the command is listed with what it does */
        CHECK_INT(run((const char *[]){gonioctl, "wait", "--help", NULL}, &out, &err), 0);
        CHECK_STR_CONTAINS(out, "--state STATE");
        free(out);
        free(err);
        /* a group lists its commands; an unknown command is a usage error */
        CHECK_INT(run((const char *[]){gonioctl, "session", "--help", NULL}, &out, &err), 0);
        CHECK_STR_CONTAINS(out, "  session resume [DATASET]");
        free(out);
        free(err);
        CHECK_INT(run((const char *[]){gonioctl, "frobnicate", "--help", NULL}, &out, &err), 2);
        free(out);
        free(err);
}

static void json_errors(void)
{
        static const struct {
                int exit;
                const char *code, *msg, *args[6];
        } cases[] = {
                {2, "usage", "frob: unknown command", {"frob"}},
                {2, "usage", "--frob: unknown option", {"--frob", "status"}},
                {2, "usage", "missing arguments", {"move", "turntable"}},
                {2, "usage", "unknown state 'sleeping'", {"wait", "--state", "sleeping"}},
                {3,
                 "connect",
                 "connect: /nonexistent/goniod.sock",
                 {"--socket", "/nonexistent/goniod.sock", "status"}},
                {3,
                 "connect",
                 "connect: ",
                 {"--socket", "/nonexistent/goniod.sock", "--quiet", "wait"}},
        };

        for (size_t i = 0; i < sizeof(cases) / sizeof(cases[0]); i++) {
                json_t *e = json_error(cases[i].exit, cases[i].code, cases[i].args);

                CHECK_STR_CONTAINS(json_string_value(json_object_get(e, "message")), cases[i].msg);
                json_decref(e);
        }
}

static void cleanup(void)
{
        char cmd[128];

        snprintf(cmd, sizeof(cmd), "rm -rf %s", tmpdir);
        (void)!system(cmd);
}

int main(int argc, char **argv)
{
        static const struct test_case cases[] = {
                {"validate-examples", validate_examples},
                {"validate-broken", validate_broken},
                {"version", versions},
                {"help", help},
                {"json-errors", json_errors},
        };

        CHECK(argc >= 6);
        gonioctl = argv[1];
        goniod = argv[2];
        gonio_sim = argv[3];
        srcdir = argv[4];
        version = argv[5];
        snprintf(tmpdir, sizeof(tmpdir), "/tmp/test-opcli-XXXXXX");
        CHECK(mkdtemp(tmpdir));
        atexit(cleanup);
        return TEST_RUN_CASES(cases, argc - 5, argv + 5);
}
