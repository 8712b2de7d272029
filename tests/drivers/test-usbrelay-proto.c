/* test-usbrelay-proto.c - the pure side of the "usbrelay" switch backend: the 8-byte HID
 * feature reports of the relay boards (commands, the serial and relay bitmask a GET_REPORT
 * returns), the product string "USBRelayN", and the backend's rig-file map (serial, relay,
 * errors at their line, two switches on one relay of one board refused). */
#include <errno.h>
#include <stdint.h>

#include "drivers/registry.h"
#include "drivers/switch/usbrelay/proto.h"
#include "tests/test.h"

static void test_encode(void)
{
        uint8_t r[USBRELAY_REPORT_LEN];

        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_ON, 3, NULL), 0);
        CHECK(memcmp(r, (uint8_t[]){0xff, 3, 0, 0, 0, 0, 0, 0}, 8) == 0);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_OFF, 8, NULL), 0);
        CHECK(memcmp(r, (uint8_t[]){0xfd, 8, 0, 0, 0, 0, 0, 0}, 8) == 0);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_ALL_ON, 0, NULL), 0);
        CHECK(memcmp(r, (uint8_t[]){0xfe, 0, 0, 0, 0, 0, 0, 0}, 8) == 0);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_ALL_OFF, 0, NULL), 0);
        CHECK(memcmp(r, (uint8_t[]){0xfc, 0, 0, 0, 0, 0, 0, 0}, 8) == 0);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_SET_SERIAL, 0, "GONIO"), 0);
        CHECK(memcmp(r, (uint8_t[]){0xfa, 'G', 'O', 'N', 'I', 'O', 0, 0}, 8) == 0);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_ON, 0, NULL), -EINVAL);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_OFF, 9, NULL), -EINVAL);
        CHECK_INT(usbrelay_encode(r, USBRELAY_CMD_SET_SERIAL, 0, "TOOLONG"), -EINVAL);
        CHECK_INT(usbrelay_encode(r, (enum usbrelay_cmd)0x42, 1, NULL), -EINVAL);
        CHECK_INT(usbrelay_switch_cmd(true), USBRELAY_CMD_ON);
        CHECK_INT(usbrelay_switch_cmd(false), USBRELAY_CMD_OFF);
}

static void test_decode(void)
{
        /* as the firmware answers: serial, NUL (u1f35c) or a 6th byte, zero, bitmask */
        const uint8_t a[8] = {'Q', 'A', 'A', 'M', 'Z', 0, 0, 0x05};
        const uint8_t b[8] = {'U', 'N', 'S', 'E', 'T', 0, 0, 0};
        const uint8_t bad[8] = {'A', 0x01, 'C', 'D', 'E', 0, 0, 0};
        struct usbrelay_status st;

        CHECK_INT(usbrelay_decode(a, 8, &st), 0);
        CHECK_STR(st.serial, "QAAMZ");
        CHECK_INT(st.state, 0x05);
        CHECK(usbrelay_relay_on(st.state, 1));
        CHECK(!usbrelay_relay_on(st.state, 2));
        CHECK(usbrelay_relay_on(st.state, 3));
        CHECK(!usbrelay_relay_on(0xff, 0));
        CHECK(!usbrelay_relay_on(0xff, 9));
        CHECK(usbrelay_relay_on(0x80, 8));
        CHECK_INT(usbrelay_decode(b, 8, &st), 0);
        CHECK_STR(st.serial, "UNSET");
        CHECK_INT(st.state, 0);
        CHECK_INT(usbrelay_decode(a, 7, &st), -EPROTO);
        CHECK_INT(usbrelay_decode(bad, 8, &st), -EPROTO);
}

static void test_product(void)
{
        CHECK_INT(usbrelay_parse_product("USBRelay1"), 1);
        CHECK_INT(usbrelay_parse_product("USBRelay2"), 2);
        CHECK_INT(usbrelay_parse_product("USBRelay8"), 8);
        CHECK_INT(usbrelay_parse_product("USBRelay0"), -ENODEV);
        CHECK_INT(usbrelay_parse_product("USBRelay9"), -ENODEV);
        CHECK_INT(usbrelay_parse_product("USBRelay"), -ENODEV);
        CHECK_INT(usbrelay_parse_product("USBRelay2x"), -ENODEV);
        CHECK_INT(usbrelay_parse_product("HIDRelay"), -ENODEV);
        CHECK_INT(usbrelay_parse_product(NULL), -ENODEV);
        CHECK(usbrelay_serial_valid("AB12Z"));
        CHECK(!usbrelay_serial_valid("AB12"));
        CHECK(!usbrelay_serial_valid("AB 12"));
        CHECK(!usbrelay_serial_valid(NULL));
}

/* Loads rig text; err gets the message. */
static int load(const char *text, struct rig_config **rc, char *err, size_t len)
{
        char path[] = "/tmp/gonio-usbrelay-XXXXXX";
        int fd = mkstemp(path), r;

        CHECK(fd >= 0);
        CHECK(write(fd, text, strlen(text)) == (ssize_t)strlen(text));
        close(fd);
        r = rigconf_load(path, registry_backends, rc, err, len);
        unlink(path);
        return r;
}

#define RIG   "rig: t\nbuses:\n  - { name: usb, type: local }\nlamps:\n"
#define LAMP  "  - { name: %s, elevation: 1, usbrelay: { bus: usb%s } }\n"
#define LAMPS RIG LAMP LAMP

static void expect_err(const char *a, const char *b, const char *msg)
{
        struct rig_config *rc = NULL;
        char text[512], err[512] = "";

        snprintf(text, sizeof(text), LAMPS, "l1", a, "l2", b);
        CHECK_INT(load(text, &rc, err, sizeof(err)), -EINVAL);
        CHECK_STR_CONTAINS(err, msg);
}

static void test_conf(void)
{
        struct rig_config *rc = NULL;
        const struct usbrelay_conf *c;
        char text[512], err[512] = "";

        snprintf(text, sizeof(text), LAMPS, "l1", ", serial: QAAMZ, relay: 2", "l2", "");
        CHECK_INT(load(text, &rc, err, sizeof(err)), 0);
        c = rc->lamps[0].backend.conf;
        CHECK_STR(c->serial, "QAAMZ");
        CHECK_INT(c->relay, 2);
        c = rc->lamps[1].backend.conf;
        CHECK_STR(c->serial, "");
        CHECK_INT(c->relay, 1);
        rc = rigconf_free(rc);
        /* one relay number on two boards */
        snprintf(text, sizeof(text), LAMPS, "l1", ", serial: AAAAA", "l2", ", serial: BBBBB");
        CHECK_INT(load(text, &rc, err, sizeof(err)), 0);
        rc = rigconf_free(rc);

        expect_err("", ", relay: 9", ":6: key 'relay'");
        expect_err("", ", relay: 0", ":6: key 'relay'");
        expect_err("", ", serial: ABC", ":6: key 'serial': 'ABC' is not a board serial");
        expect_err("", ", rely: 2", ":6: key 'rely': unknown key");
        expect_err(", serial: AAAAA", ", serial: AAAAA",
                   "lamp 'l1' and lamp 'l2' are both on serial");
        expect_err(", relay: 2", ", relay: 2", "lamp 'l1' and lamp 'l2' are both on relay 2");
}

int main(void)
{
        test_encode();
        test_decode();
        test_product();
        test_conf();
        return 0;
}
