/* proto.h - the "usbrelay" switch backend: one relay of a USB HID relay board (16c0:05df,
 * product "USBRelayN", www.dcttech.com V-USB firmware). Pure encoding and decoding of the
 * board's 8-byte HID feature reports and of its rig-file map, no I/O (docs/drivers.md). */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "common/rigconf.h"
#include "drivers/switch/switch.h"

#define USBRELAY_VID        0x16c0
#define USBRELAY_PID        0x05df
#define USBRELAY_PRODUCT    "USBRelay" /* followed by the relay count */
#define USBRELAY_REPORT_LEN 8
#define USBRELAY_SERIAL_LEN 5
#define USBRELAY_RELAYS_MAX 8

/* HID class requests and the wValue the board is sent (feature report, id 0: the firmware
 * ignores wValue, hosts send this). */
#define USBRELAY_GET_REPORT    0x01
#define USBRELAY_SET_REPORT    0x09
#define USBRELAY_REPORT_WVALUE 0x0300

/* First byte of a SET_REPORT: the command. */
enum usbrelay_cmd {
        USBRELAY_CMD_ON = 0xff,         /* relay n (second byte) on */
        USBRELAY_CMD_ALL_ON = 0xfe,     /* every relay on */
        USBRELAY_CMD_OFF = 0xfd,        /* relay n off */
        USBRELAY_CMD_ALL_OFF = 0xfc,    /* every relay off */
        USBRELAY_CMD_SET_SERIAL = 0xfa, /* the 5 bytes after it become the serial */
};

/* What the backend reads from "usbrelay: { bus: usb, serial: ABCDE, relay: 1 }". */
struct usbrelay_conf {
        char serial[USBRELAY_SERIAL_LEN + 1]; /* "": the bus's only board */
        int relay;                            /* 1-based; 1 when not given */
};

/* What a GET_REPORT tells. */
struct usbrelay_status {
        char serial[USBRELAY_SERIAL_LEN + 1];
        uint8_t state; /* bit n-1: relay n on */
};

/* The backend (api.c), registered in drivers/registry.c as "usbrelay". */
extern const struct sw_ops usbrelay_ops;
extern const struct rig_backend usbrelay_backend;

/* Parses the backend map m into conf (a struct usbrelay_conf) and addr (relay, with the
 * serial as sub-address): unknown keys, a serial that is not 5 printable characters and a
 * relay outside 1..8 are errors at their key's line. Returns 0 or -EINVAL. Pure. */
int usbrelay_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                        void *conf, struct rig_addr *addr);

/* Whether s is a board serial: 5 printable ASCII characters other than space. */
bool usbrelay_serial_valid(const char *s);

/* Encodes a SET_REPORT command into r: cmd, then relay for ON/OFF, the 5 serial bytes of arg
 * for SET_SERIAL (arg NULL otherwise). Returns 0, or -EINVAL for a relay outside 1..8, a
 * bad serial or an unknown command. */
int usbrelay_encode(uint8_t r[USBRELAY_REPORT_LEN], enum usbrelay_cmd cmd, int relay,
                    const char *arg);

/* The command that switches relay (1-based) on or off. */
enum usbrelay_cmd usbrelay_switch_cmd(bool on);

/* Decodes a GET_REPORT answer of len bytes: the serial (bytes 0..4, a NUL-terminated copy)
 * and the relay bitmask (byte 7). Returns 0, -EPROTO for a short report or a serial of
 * unprintable bytes. */
int usbrelay_decode(const uint8_t *r, int len, struct usbrelay_status *st);

/* The relay count of a board from its product string "USBRelayN". Returns 1..8, or -ENODEV
 * when product does not name a relay board (or N is out of range). */
int usbrelay_parse_product(const char *product);

/* Whether relay (1-based) is on in state. */
bool usbrelay_relay_on(uint8_t state, int relay);

/* A 31-bit number standing for serial, for struct rig_addr (two devices with the same
 * relay on boards of different serials do not clash). */
int usbrelay_serial_key(const char *serial);
