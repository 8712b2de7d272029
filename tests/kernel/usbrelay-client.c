/* usbrelay-client.c - kernel lane self-test: a libusb-1.0 client of a USB HID relay board
 * (16c0:05df, product "USBRelayN"), as gonio's USB relay backend will talk to one: enumeration by
 * vid:pid, the relay count from the product string, the HID report descriptor, and HID feature
 * reports to switch relays and read them back (and the serial). Each switch is also checked in
 * the emulator's STATEFILE, so the result is seen by something other than the client. Reports
 * are encoded and decoded by the usbrelay backend's proto.c, the transfers are the client's own.
 *
 * Usage: kl-usbrelay-client [STATEFILE] (run kl-usbrelay-emu first). */
#include <libusb.h>
#include <time.h>

#include "common/cleanup.h"
#include "drivers/switch/usbrelay/proto.h"
#include "tests/test.h"

#define TIMEOUT_MS 1000

static const char *state_file;

/* Opens the board, waiting for its enumeration after the gadget binds. libusb learns of devices
 * that come later from udevd only, and the lane has none: a new context rescans. */
static libusb_device_handle *open_board(libusb_context **ctx)
{
        for (int i = 0; i < 100; i++) {
                libusb_device_handle *h;

                CHECK_INT(libusb_init(ctx), 0);
                h = libusb_open_device_with_vid_pid(*ctx, USBRELAY_VID, USBRELAY_PID);
                if (h)
                        return h;
                libusb_exit(*ctx);
                nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
        }
        return NULL;
}

/* Reads the 8-byte feature report: serial in serial[6], returns the relay state bitmask. */
static int get_report(libusb_device_handle *h, char serial[6])
{
        uint8_t r[USBRELAY_REPORT_LEN];
        struct usbrelay_status st;
        int n = libusb_control_transfer(
                h, LIBUSB_ENDPOINT_IN | LIBUSB_REQUEST_TYPE_CLASS | LIBUSB_RECIPIENT_INTERFACE,
                USBRELAY_GET_REPORT, USBRELAY_REPORT_WVALUE, 0, r, sizeof(r), TIMEOUT_MS);

        CHECK_INT(n, USBRELAY_REPORT_LEN);
        CHECK_INT(usbrelay_decode(r, n, &st), 0);
        memcpy(serial, st.serial, sizeof(st.serial));
        return st.state;
}

/* Sends command cmd with relay (ON/OFF) or the serial arg (SET_SERIAL). */
static void set_report(libusb_device_handle *h, enum usbrelay_cmd cmd, int relay, const char *arg)
{
        uint8_t r[USBRELAY_REPORT_LEN];

        CHECK_INT(usbrelay_encode(r, cmd, relay, arg), 0);
        CHECK_INT(libusb_control_transfer(h,
                                          LIBUSB_ENDPOINT_OUT | LIBUSB_REQUEST_TYPE_CLASS |
                                                  LIBUSB_RECIPIENT_INTERFACE,
                                          USBRELAY_SET_REPORT, USBRELAY_REPORT_WVALUE, 0, r,
                                          sizeof(r), TIMEOUT_MS),
                  USBRELAY_REPORT_LEN);
}

/* Checks the state both as the board reports it and as the emulator's outputs show it. */
static void expect_state(libusb_device_handle *h, int state)
{
        char serial[6], line[8] = "";
        _cleanup_fclose_ FILE *f = NULL;

        CHECK_INT(get_report(h, serial), state);
        if (!state_file)
                return;
        f = fopen(state_file, "re");
        CHECK(f && fgets(line, sizeof(line), f));
        CHECK_INT(strtol(line, NULL, 16), state);
}

static void switch_relays(libusb_device_handle *h, unsigned relays)
{
        int all = (1 << relays) - 1;

        expect_state(h, 0);
        for (unsigned i = 1; i <= relays; i++) {
                set_report(h, USBRELAY_CMD_ON, (int)i, NULL);
                expect_state(h, (1 << i) - 1);
        }
        if (relays < USBRELAY_RELAYS_MAX) {
                set_report(h, USBRELAY_CMD_ON, (int)relays + 1, NULL); /* ignored */
                expect_state(h, all);
        }
        set_report(h, USBRELAY_CMD_OFF, 1, NULL);
        expect_state(h, all & ~1);
        set_report(h, USBRELAY_CMD_ALL_OFF, 0, NULL);
        expect_state(h, 0);
        set_report(h, USBRELAY_CMD_ALL_ON, 0, NULL);
        expect_state(h, all);
        set_report(h, USBRELAY_CMD_ALL_OFF, 0, NULL);
        expect_state(h, 0);
}

static void check_identity(libusb_device_handle *h, unsigned *relays)
{
        struct libusb_device_descriptor dd;
        unsigned char product[64], desc[64];
        char serial[6];

        CHECK_INT(libusb_get_device_descriptor(libusb_get_device(h), &dd), 0);
        CHECK(libusb_get_string_descriptor_ascii(h, dd.iProduct, product, sizeof(product)) > 0);
        CHECK(usbrelay_parse_product((char *)product) > 0);
        *relays = (unsigned)usbrelay_parse_product((char *)product);
        CHECK_INT(libusb_control_transfer(h, LIBUSB_ENDPOINT_IN | LIBUSB_RECIPIENT_INTERFACE,
                                          LIBUSB_REQUEST_GET_DESCRIPTOR, 0x2200, 0, desc,
                                          sizeof(desc), TIMEOUT_MS),
                  22);
        CHECK(desc[0] == 0x06 && desc[1] == 0x00 && desc[2] == 0xff); /* vendor usage page */
        get_report(h, serial);
        CHECK_INT(strlen(serial), 5);
        set_report(h, USBRELAY_CMD_SET_SERIAL, 0, "GONIO");
        get_report(h, serial);
        CHECK_STR(serial, "GONIO");
        printf("%s: %u relays, serial %s\n", product, *relays, serial);
}

int main(int argc, char **argv)
{
        libusb_context *ctx = NULL;
        libusb_device_handle *h;
        unsigned relays;

        state_file = argc > 1 ? argv[1] : NULL;
        h = open_board(&ctx);
        CHECK(h);
        CHECK_INT(libusb_set_auto_detach_kernel_driver(h, 1), 0);
        CHECK_INT(libusb_claim_interface(h, 0), 0);
        check_identity(h, &relays);
        switch_relays(h, relays);
        libusb_release_interface(h, 0);
        libusb_close(h);
        libusb_exit(ctx);
        return 0;
}
