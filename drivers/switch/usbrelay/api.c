/* api.c - the "usbrelay" switch backend: a lamp or laser on one relay of a USB HID relay
 * board. The switches of one board share its handle (board.c); a switch counts as switched
 * only once the board's feature report, read back, confirms it. */
#include <errno.h>

#include "common/cleanup.h"
#include "common/log.h"
#include "drivers/switch/usbrelay/board.h"
#include "drivers/switch/usbrelay/proto.h"

static const struct opt_desc usbrelay_opts[] = {
        {OPT_STATE, OPT_GET | OPT_SET},
};

static const struct usbrelay_conf *conf(const struct sw *s)
{
        return s->conf->backend.conf;
}

/* Opens the board, or reopens it after an unplug (fault.clear), and checks the relay. */
static int usbrelay_open(struct sw *s)
{
        struct usbrelay_board *b;
        int r;

        if (!conf(s))
                return sw_set_cause(s, SYNTHETIC_ERRNO(EINVAL), "no relay in the rig file");
        if (!s->priv || usbrelay_board_lost(s->priv)) {
                r = usbrelay_board_get(s, &b);
                if (r < 0)
                        return r;
                usbrelay_board_put(s->priv);
                s->priv = b;
        }
        b = s->priv;
        if (conf(s)->relay > usbrelay_board_relays(b))
                return sw_set_cause(s, SYNTHETIC_ERRNO(EINVAL),
                                    "relay %d, but board %s has %d (USBRelay%d)", conf(s)->relay,
                                    usbrelay_board_serial(b), usbrelay_board_relays(b),
                                    usbrelay_board_relays(b));
        return 0;
}

static void usbrelay_close(struct sw *s)
{
        s->priv = usbrelay_board_put(s->priv);
}

/* The open board; -ENODEV with the cause when the switch never opened. */
static int board(struct sw *s, struct usbrelay_board **b)
{
        *b = s->priv;
        if (!*b)
                return sw_set_cause(s, SYNTHETIC_ERRNO(ENODEV),
                                    "board not open (fault.clear opens it)");
        return 0;
}

static int usbrelay_get(struct sw *s, bool *on)
{
        struct usbrelay_board *b;
        uint8_t state;
        int r;

        if ((r = board(s, &b)) < 0 || (r = usbrelay_board_read(b, s, &state)) < 0)
                return r;
        *on = usbrelay_relay_on(state, conf(s)->relay);
        return 0;
}

static int usbrelay_set(struct sw *s, bool on)
{
        struct usbrelay_board *b;
        uint8_t state;
        int r;

        if ((r = board(s, &b)) < 0 ||
            (r = usbrelay_board_switch(b, s, conf(s)->relay, on, &state)) < 0)
                return r;
        if (usbrelay_relay_on(state, conf(s)->relay) != on)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EIO),
                                    "relay %d of board %s reads %s after switching it %s",
                                    conf(s)->relay, usbrelay_board_serial(b), on ? "off" : "on",
                                    on ? "on" : "off");
        return 0;
}

const struct rig_backend usbrelay_backend = {
        .name = "usbrelay",
        .cls = RIG_CLASS_SWITCH,
        .bus_types = 1u << RIG_BUS_LOCAL,
        .conf_size = sizeof(struct usbrelay_conf),
        .parse_conf = usbrelay_parse_conf,
        .ops = &usbrelay_ops,
};

const struct sw_ops usbrelay_ops = {
        .name = "usbrelay",
        .opts = usbrelay_opts,
        .n_opts = ELEMENTSOF(usbrelay_opts),
        .open = usbrelay_open,
        .close = usbrelay_close,
        .set = usbrelay_set,
        .get = usbrelay_get,
};
