/* proto.c - pure encoding and decoding for the "usbrelay" switch backend: the board's HID
 * feature reports, its product string and its rig-file map. */
#include <errno.h>
#include <stdlib.h>
#include <string.h>

#include "drivers/switch/usbrelay/proto.h"

int usbrelay_parse_conf(struct yconf *yc, struct fy_node *m, const struct rig_config *rc,
                        void *conf, struct rig_addr *addr)
{
        static const char *const keys[] = {"bus", "serial", "relay", NULL};
        struct usbrelay_conf *c = conf;
        char serial[64] = "";
        long relay = 1;
        int r;

        if ((r = yconf_check_keys(yc, m, keys)) < 0 ||
            (r = yconf_str(yc, m, "serial", serial, sizeof(serial))) < 0 ||
            (r = yconf_int(yc, m, "relay", 1, USBRELAY_RELAYS_MAX, &relay)) < 0)
                return r;
        if (serial[0] && !usbrelay_serial_valid(serial))
                return yconf_error(yc, yconf_get(m, "serial"), "serial",
                                   "'%s' is not a board serial (5 printable characters)", serial);
        *c = (struct usbrelay_conf){.relay = (int)relay};
        strcpy(c->serial, serial);
        *addr = (struct rig_addr){.key = "relay", .value = c->relay};
        if (serial[0])
                *addr = (struct rig_addr){.key = "relay",
                                          .value = c->relay,
                                          .sub_key = "serial",
                                          .sub = usbrelay_serial_key(serial)};
        return 0;
}

bool usbrelay_serial_valid(const char *s)
{
        if (!s || strlen(s) != USBRELAY_SERIAL_LEN)
                return false;
        for (; *s; s++)
                if (*s <= ' ' || *s > '~')
                        return false;
        return true;
}

enum usbrelay_cmd usbrelay_switch_cmd(bool on)
{
        return on ? USBRELAY_CMD_ON : USBRELAY_CMD_OFF;
}

int usbrelay_encode(uint8_t r[USBRELAY_REPORT_LEN], enum usbrelay_cmd cmd, int relay,
                    const char *arg)
{
        memset(r, 0, USBRELAY_REPORT_LEN);
        r[0] = (uint8_t)cmd;
        switch (cmd) {
        case USBRELAY_CMD_ON:
        case USBRELAY_CMD_OFF:
                if (relay < 1 || relay > USBRELAY_RELAYS_MAX)
                        return -EINVAL;
                r[1] = (uint8_t)relay;
                return 0;
        case USBRELAY_CMD_ALL_ON:
        case USBRELAY_CMD_ALL_OFF:
                return 0;
        case USBRELAY_CMD_SET_SERIAL:
                if (!usbrelay_serial_valid(arg))
                        return -EINVAL;
                memcpy(r + 1, arg, USBRELAY_SERIAL_LEN);
                return 0;
        }
        return -EINVAL;
}

int usbrelay_decode(const uint8_t *r, int len, struct usbrelay_status *st)
{
        if (len < USBRELAY_REPORT_LEN)
                return -EPROTO;
        memset(st->serial, 0, sizeof(st->serial));
        for (int i = 0; i < USBRELAY_SERIAL_LEN && r[i]; i++) {
                if (r[i] <= ' ' || r[i] > '~')
                        return -EPROTO;
                st->serial[i] = (char)r[i];
        }
        st->state = r[7];
        return 0;
}

int usbrelay_parse_product(const char *product)
{
        size_t n = strlen(USBRELAY_PRODUCT);
        char *end;
        long relays;

        if (!product || strncmp(product, USBRELAY_PRODUCT, n) != 0 || product[n] < '0' ||
            product[n] > '9')
                return -ENODEV;
        relays = strtol(product + n, &end, 10);
        if (*end || relays < 1 || relays > USBRELAY_RELAYS_MAX)
                return -ENODEV;
        return (int)relays;
}

bool usbrelay_relay_on(uint8_t state, int relay)
{
        return relay >= 1 && relay <= USBRELAY_RELAYS_MAX && (state >> (relay - 1) & 1);
}

int usbrelay_serial_key(const char *serial)
{
        uint32_t h = 2166136261u; /* FNV-1a */

        for (; *serial; serial++)
                h = (h ^ (uint8_t)*serial) * 16777619u;
        return (int)(h & 0x7fffffff);
}
