/* usbrelay-backend.c - kernel lane test of the "usbrelay" switch backend against emulated USB
 * HID relay boards (kl-usbrelay-emu: FunctionFS gadgets on dummy_hcd, usbhid bound to them):
 * lamps and a laser on two boards told apart by serial, switched through the switch class and
 * checked in each emulator's state file (what the relays do, seen by something other than
 * the driver); usbhid detached while the backend holds a board and back after; the switches
 * of one board share one handle; a board another process holds is -EBUSY; a relay that does not
 * follow its command is an error and leaves the cached state alone; a relay the board lacks, a
 * serial no board has and several boards without a serial are clear errors; a board unplugged (its
 * gadget unbound) gives -ENODEV with a clear message while the other board works on, and once
 * plugged back in sw_open (what fault.clear calls) reopens it.
 *
 * Usage: kl-usbrelay-backend EMULATOR (the path of kl-usbrelay-emu); run as root in the lane. */
#include <glob.h>
#include <spawn.h>
#include <sys/wait.h>
#include <time.h>

#include "common/cleanup.h"
#include "drivers/bus/bus.h"
#include "drivers/registry.h"
#include "drivers/switch/switch.h"
#include "tests/test.h"

#define GADGET_A "/sys/kernel/config/usb_gadget/relay-a/UDC"

/* Board A: 2 relays, serial ABCDE; board B: 4 relays, serial FGHIJ, relay 3 stuck. */
static const char rig[] =
        "rig: usbrelay\n"
        "buses:\n"
        "  - { name: usb, type: local }\n"
        "  - { name: usb2, type: local }\n"
        "lamps:\n"
        "  - { name: a1, elevation: 1, usbrelay: { bus: usb, serial: ABCDE, relay: 1 } }\n"
        "  - { name: a2, elevation: 1, usbrelay: { bus: usb, serial: ABCDE, relay: 2 } }\n"
        "  - { name: b4, elevation: 1, usbrelay: { bus: usb, serial: FGHIJ, relay: 4 } }\n"
        "  - { name: a3, elevation: 1, usbrelay: { bus: usb, serial: ABCDE, relay: 3 } }\n"
        "  - { name: zz, elevation: 1, usbrelay: { bus: usb, serial: ZZZZZ } }\n"
        "  - { name: any, elevation: 1, usbrelay: { bus: usb2 } }\n"
        "  - { name: b3, elevation: 1, usbrelay: { bus: usb, serial: FGHIJ, relay: 3 } }\n"
        "laser: { name: laser, usbrelay: { bus: usb, serial: FGHIJ, relay: 1 } }\n";

enum { A1, A2, B4, A3, ZZ, ANY, B3, LASER, N_SW };

static struct sw *sw[N_SW];

static void run(char *const argv[])
{
        pid_t pid;
        int status;

        CHECK_INT(posix_spawn(&pid, argv[0], NULL, NULL, argv, NULL), 0);
        CHECK(waitpid(pid, &status, 0) == pid);
        CHECK(WIFEXITED(status) && WEXITSTATUS(status) == 0);
}

/* The relay outputs of an emulated board, from its state file. */
static int outputs(const char *state_file)
{
        _cleanup_fclose_ FILE *f = fopen(state_file, "re");
        char line[8] = "";

        CHECK(f && fgets(line, sizeof(line), f));
        return (int)strtol(line, NULL, 16);
}

static void write_file(const char *path, const char *value)
{
        _cleanup_fclose_ FILE *f = fopen(path, "we");

        CHECK(f && fputs(value, f) >= 0 && fflush(f) == 0);
}

/* The kernel driver bound to the interface of the board whose product is product, "" when
 * none. */
static void iface_driver(const char *product, char *driver, size_t len)
{
        glob_t g = {0};

        driver[0] = '\0';
        CHECK_INT(glob("/sys/bus/usb/devices/*/product", 0, NULL, &g), 0);
        for (size_t i = 0; i < g.gl_pathc; i++) {
                _cleanup_fclose_ FILE *f = fopen(g.gl_pathv[i], "re");
                char line[32] = "", link[512], target[256] = "";
                char *dir = g.gl_pathv[i], *slash = strrchr(dir, '/');

                if (!f || !fgets(line, sizeof(line), f) || strncmp(line, product, strlen(product)))
                        continue;
                *slash = '\0';
                snprintf(link, sizeof(link), "%s/%s:1.0/driver", dir, strrchr(dir, '/') + 1);
                if (readlink(link, target, sizeof(target) - 1) > 0)
                        snprintf(driver, len, "%s", strrchr(target, '/') + 1);
        }
        globfree(&g);
}

/* Expects the board's interface to be bound to driver want ("": none) within 2 s: the
 * kernel binds usbhid some time after the board is configured. */
static void expect_driver(const char *product, const char *want)
{
        char driver[64] = "?";

        for (int i = 0; i < 40 && strcmp(driver, want) != 0; i++) {
                if (i)
                        nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
                iface_driver(product, driver, sizeof(driver));
        }
        CHECK_STR(driver, want);
}

/* Expects sw_open of switch i to fail with err and a message containing msg. */
static void expect_open_fails(int i, int err, const char *msg)
{
        CHECK_INT(sw_open(sw[i]), err);
        CHECK_STR_CONTAINS(sw[i]->last_error, msg);
}

static void switch_and_check(int i, bool on, const char *state_file, int outputs_want)
{
        bool now;

        CHECK_INT(sw_set(sw[i], on), 0);
        CHECK(sw[i]->on == on);
        CHECK_INT(outputs(state_file), outputs_want);
        CHECK_INT(sw_get(sw[i], &now), 0);
        CHECK(now == on);
}

/* Several boards and no serial; a serial no board has. Run before the others are open: a
 * board held by gonio is not enumerated again. */
static void test_choice(void)
{
        expect_open_fails(ANY, -ENOTUNIQ, "several USB relay boards (");
        expect_open_fails(ZZ, -ENODEV, "no USB relay board (16c0:05df) with serial ZZZZZ (found: ");
}

/* A board held by another process: a child opens the laser's board (FGHIJ) and holds it
 * until told; the board's other switches cannot have it meanwhile. */
static void test_busy(void)
{
        int ready[2], done[2], status;
        char c = 0;
        pid_t pid;

        CHECK(pipe(ready) == 0 && pipe(done) == 0);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                bool held = sw_open(sw[LASER]) == 0;

                if (write(ready[1], held ? "y" : "n", 1) == 1)
                        (void)!read(done[0], &c, 1);
                sw[LASER] = sw_free(sw[LASER]); /* usbhid gets it back */
                _exit(0);
        }
        CHECK(read(ready[0], &c, 1) == 1 && c == 'y');
        expect_open_fails(B4, -EBUSY,
                          "no USB relay board (16c0:05df) with serial FGHIJ (found: ABCDE; USB "
                          "relay board ");
        CHECK_STR_CONTAINS(sw[B4]->last_error, ": in use by another program)");
        CHECK(write(done[1], "x", 1) == 1);
        CHECK(waitpid(pid, &status, 0) == pid && WIFEXITED(status) && WEXITSTATUS(status) == 0);
        for (int i = 0; i < 2; i++) {
                close(ready[i]);
                close(done[i]);
        }
}

static void test_switching(void)
{
        expect_driver("USBRelay2", "usbhid");
        CHECK_INT(sw_open(sw[A1]), 0);
        expect_driver("USBRelay2", "usbfs"); /* usbhid detached: gonio holds the board */
        expect_driver("USBRelay4", "usbhid");
        CHECK_INT(sw_open(sw[A2]), 0);
        CHECK_INT(sw_open(sw[B4]), 0);
        CHECK_INT(sw_open(sw[LASER]), 0);
        CHECK(sw[A1]->priv == sw[A2]->priv); /* one handle per board */
        CHECK(sw[B4]->priv == sw[LASER]->priv && sw[B4]->priv != sw[A1]->priv);
        expect_open_fails(A3, -EINVAL, "relay 3, but board ABCDE has 2 (USBRelay2)");
        /* again, now that the board is open */
        expect_open_fails(A3, -EINVAL, "relay 3, but board ABCDE has 2 (USBRelay2)");

        switch_and_check(A1, true, "a.state", 0x01);
        switch_and_check(A2, true, "a.state", 0x03);
        switch_and_check(B4, true, "b.state", 0x08);
        switch_and_check(LASER, true, "b.state", 0x09);
        switch_and_check(A1, false, "a.state", 0x02);
        switch_and_check(LASER, false, "b.state", 0x08);
        CHECK_INT(outputs("a.state"), 0x02);

        /* a relay that does not follow: refused, and the cached state stays */
        CHECK_INT(sw_open(sw[B3]), 0);
        CHECK_INT(sw_set(sw[B3], true), -EIO);
        CHECK_STR_CONTAINS(sw[B3]->last_error, "relay 3 of board FGHIJ reads off after switching "
                                               "it on");
        CHECK(!sw[B3]->on);
        CHECK_INT(outputs("b.state"), 0x08);
}

/* Waits (up to 5 s) until a board with product is on the bus (present) or gone. */
static void wait_board(const char *product, bool present)
{
        glob_t g = {0};
        bool found = !present;

        for (int i = 0; i < 100 && found != present; i++) {
                nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
                found = false;
                if (glob("/sys/bus/usb/devices/*/product", 0, NULL, &g) == 0)
                        for (size_t k = 0; k < g.gl_pathc; k++) {
                                _cleanup_fclose_ FILE *f = fopen(g.gl_pathv[k], "re");
                                char line[32] = "";

                                found |= f && fgets(line, sizeof(line), f) &&
                                         strncmp(line, product, strlen(product)) == 0;
                        }
                globfree(&g);
        }
        CHECK(found == present);
}

/* sw_open of switch i, as fault.clear calls it, until the replugged board is enumerated. */
static void reopen(int i)
{
        int r = -ENODEV;

        for (int k = 0; k < 100 && r == -ENODEV; k++) {
                r = sw_open(sw[i]);
                if (r == -ENODEV)
                        nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
        }
        CHECK_INT(r, 0);
}

static void test_unplug(void)
{
        _cleanup_fclose_ FILE *f = fopen(GADGET_A, "re");
        char udc[64] = "";
        bool on;

        CHECK(f && fgets(udc, sizeof(udc), f));
        write_file(GADGET_A, "\n"); /* unplugged */
        wait_board("USBRelay2", false);
        for (int i = 0; i < 40 && outputs("a.state") != 0; i++) /* the emulator's own pace */
                nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
        CHECK_INT(outputs("a.state"), 0); /* its relays dropped with the power */
        CHECK_INT(sw_set(sw[A2], false), -ENODEV);
        CHECK_STR_CONTAINS(sw[A2]->last_error, "Failed to switch off: USB relay board ABCDE is "
                                               "gone (unplugged?) while switching off");
        CHECK(sw[A2]->on); /* not confirmed: unchanged */
        CHECK_INT(sw_get(sw[A1], &on), -ENODEV);
        CHECK_STR_CONTAINS(sw[A1]->last_error, "ABCDE was unplugged; fault.clear reopens it");
        switch_and_check(B4, false, "b.state", 0x00); /* the other board works on */
        expect_open_fails(A1, -ENODEV, "with serial ABCDE (found: none)");

        write_file(GADGET_A, udc); /* plugged back in */
        wait_board("USBRelay2", true);
        reopen(A1);
        CHECK(!sw[A1]->on);
        CHECK_INT(sw_open(sw[A2]), 0);
        CHECK(!sw[A2]->on);
        CHECK(sw[A1]->priv == sw[A2]->priv);
        switch_and_check(A2, true, "a.state", 0x02);
        switch_and_check(A1, true, "a.state", 0x03);
}

int main(int argc, char **argv)
{
        const struct rig_switch_conf *confs[N_SW];
        struct bus *usb = NULL, *usb2 = NULL;
        struct rig_config *rc = NULL;
        char err[512] = "";

        CHECK(argc == 2);
        run((char *[]){argv[1], "-n", "relay-a", "-s", "ABCDE", "2", "a.state", NULL});
        run((char *[]){argv[1], "-n", "relay-b", "-s", "FGHIJ", "-k", "3", "4", "b.state", NULL});
        write_file("usbrelay-rig.yaml", rig);
        if (rigconf_load("usbrelay-rig.yaml", registry_backends, &rc, err, sizeof(err)) < 0)
                fprintf(stderr, "%s\n", err);
        CHECK(rc);
        CHECK_INT(bus_new_sync(rigconf_bus(rc, "usb"), &usb), 0);
        CHECK_INT(bus_new_sync(rigconf_bus(rc, "usb2"), &usb2), 0);
        for (int i = 0; i < LASER; i++)
                confs[i] = &rc->lamps[i];
        confs[LASER] = &rc->lasers[0];
        for (int i = 0; i < N_SW; i++)
                CHECK_INT(sw_new(confs[i], i == ANY ? usb2 : usb, &sw[i]), 0);

        expect_driver("USBRelay2", "usbhid");
        expect_driver("USBRelay4", "usbhid");
        test_choice();
        test_busy();
        test_switching();
        test_unplug();

        for (int i = 0; i < N_SW; i++)
                sw[i] = sw_free(sw[i]);
        expect_driver("USBRelay2", "usbhid"); /* given back to the kernel */
        expect_driver("USBRelay4", "usbhid");
        bus_free(usb);
        bus_free(usb2);
        rigconf_free(rc);
        printf("usbrelay backend: two boards, unplug and replug: ok\n");
        return 0;
}
