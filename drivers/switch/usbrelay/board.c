/* board.c - the "usbrelay" backend's boards over libusb-1.0: a cache of open boards keyed by
 * bus and serial, so that the switches of one board share one handle; opening by vid:pid,
 * product string "USBRelayN" and the serial of the feature report, with the kernel's driver
 * (usbhid) detached while gonio holds the board; feature reports as control transfers.
 *
 * Each board has its own libusb context, made when it is opened: where no udevd runs, a
 * context sees only the devices present when it was made, so a replugged board needs a new
 * one. The cache is shared by every bus worker (a mutex); a board is used by its own bus's
 * worker only, so its I/O needs no lock. */
#include <errno.h>
#include <libusb.h>
#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "common/log.h"
#include "drivers/switch/usbrelay/board.h"
#include "drivers/switch/usbrelay/proto.h"

#define TIMEOUT_MS 1000

struct usbrelay_board {
        struct usbrelay_board *next;
        const struct bus *bus;
        unsigned refs;
        libusb_context *ctx;
        libusb_device_handle *h; /* NULL: lost (unplugged) */
        char serial[USBRELAY_SERIAL_LEN + 1];
        int relays;
        uint8_t busnum, address; /* where the kernel has it, while open */
};

static pthread_mutex_t cache_lock = PTHREAD_MUTEX_INITIALIZER;
static struct usbrelay_board *cache;

/* -errno for a LIBUSB_ERROR_* code. */
static int usb_errno(int r)
{
        switch (r) {
        case LIBUSB_ERROR_IO:
                return -EIO;
        case LIBUSB_ERROR_INVALID_PARAM:
                return -EINVAL;
        case LIBUSB_ERROR_ACCESS:
                return -EACCES;
        case LIBUSB_ERROR_NO_DEVICE:
                return -ENODEV;
        case LIBUSB_ERROR_NOT_FOUND:
                return -ENOENT;
        case LIBUSB_ERROR_BUSY:
                return -EBUSY;
        case LIBUSB_ERROR_TIMEOUT:
                return -ETIMEDOUT;
        case LIBUSB_ERROR_OVERFLOW:
                return -EOVERFLOW;
        case LIBUSB_ERROR_PIPE:
                return -EPIPE;
        case LIBUSB_ERROR_INTERRUPTED:
                return -EINTR;
        case LIBUSB_ERROR_NO_MEM:
                return -ENOMEM;
        case LIBUSB_ERROR_NOT_SUPPORTED:
                return -EOPNOTSUPP;
        default:
                return -EIO;
        }
}

/* One HID class control transfer of the 8-byte feature report; bytes moved or LIBUSB_ERROR. */
static int feature_report(libusb_device_handle *h, bool in, uint8_t r[USBRELAY_REPORT_LEN])
{
        uint8_t type = LIBUSB_REQUEST_TYPE_CLASS | LIBUSB_RECIPIENT_INTERFACE |
                       (in ? LIBUSB_ENDPOINT_IN : LIBUSB_ENDPOINT_OUT);

        return libusb_control_transfer(h, type, in ? USBRELAY_GET_REPORT : USBRELAY_SET_REPORT,
                                       USBRELAY_REPORT_WVALUE, 0, r, USBRELAY_REPORT_LEN,
                                       TIMEOUT_MS);
}

/* Reads and decodes the feature report; 0, LIBUSB_ERROR or -EPROTO. */
static int get_status(libusb_device_handle *h, struct usbrelay_status *st)
{
        uint8_t r[USBRELAY_REPORT_LEN];
        int n = feature_report(h, true, r);

        return n < 0 ? n : usbrelay_decode(r, n, st);
}

/* Releases the interface, if claimed (the kernel's driver, if detached, comes back), and
 * closes h. */
static void release(libusb_device_handle *h)
{
        libusb_release_interface(h, 0);
        libusb_close(h);
}

/* Closes the board's handle and context. */
static void close_handle(struct usbrelay_board *b)
{
        if (b->h)
                release(b->h);
        if (b->ctx)
                libusb_exit(b->ctx);
        b->h = NULL;
        b->ctx = NULL;
}

/* Whether another open board of the cache is the device at busnum:address. */
static bool in_cache(uint8_t busnum, uint8_t address)
{
        for (struct usbrelay_board *b = cache; b; b = b->next)
                if (b->h && b->busnum == busnum && b->address == address)
                        return true;
        return false;
}

/* A board found while enumerating. */
struct found {
        libusb_device_handle *h;
        struct usbrelay_status st;
        int relays;
};

/* Identifies the open device f->h: its product string, its interface claimed (usbhid
 * detached), its feature report. Returns 1 (a relay board, f filled), 0 (another device) or
 * -errno with the cause on s. */
static int identify(struct sw *s, libusb_device *dev, const struct libusb_device_descriptor *dd,
                    struct found *f)
{
        unsigned char product[64];
        int r;

        r = libusb_get_string_descriptor_ascii(f->h, dd->iProduct, product, sizeof(product));
        f->relays = usbrelay_parse_product(r > 0 ? (char *)product : NULL);
        if (f->relays < 0)
                return 0;
        libusb_set_auto_detach_kernel_driver(f->h, 1);
        r = libusb_claim_interface(f->h, 0);
        if (r == 0)
                r = get_status(f->h, &f->st);
        if (r == 0)
                return 1;
        return sw_set_cause(s, r == -EPROTO ? r : usb_errno(r), "USB relay board %03u/%03u: %s",
                            libusb_get_bus_number(dev), libusb_get_device_address(dev),
                            r == LIBUSB_ERROR_BUSY ? "in use by another program"
                            : r == -EPROTO         ? "malformed feature report"
                                                   : libusb_strerror(r));
}

/* Opens dev if it is a relay board not yet in the cache. Returns 1 (f filled, handle open),
 * 0 (not one) or -errno with the cause on s. */
static int probe(struct sw *s, libusb_device *dev, struct found *f)
{
        struct libusb_device_descriptor dd;
        int r;

        if (libusb_get_device_descriptor(dev, &dd) < 0 || dd.idVendor != USBRELAY_VID ||
            dd.idProduct != USBRELAY_PID ||
            in_cache(libusb_get_bus_number(dev), libusb_get_device_address(dev)))
                return 0;
        r = libusb_open(dev, &f->h);
        if (r < 0)
                return sw_set_cause(s, usb_errno(r), "cannot open USB device %03u/%03u: %s",
                                    libusb_get_bus_number(dev), libusb_get_device_address(dev),
                                    libusb_strerror(r));
        r = identify(s, dev, &dd, f);
        if (r <= 0)
                release(f->h);
        return r;
}

/* After a scan found no board: why, on s, with the cause of a board that could not be
 * identified (err < 0: on s already). Returns that err (-EBUSY: the board wanted may be the
 * one in use), else -ENODEV. */
static int not_found(struct sw *s, const char *want, const char *seen, int err)
{
        char other[DEV_ERROR_MAX] = "";

        if (err < 0 && !seen[0])
                return err; /* the one failure says it */
        if (err < 0)
                snprintf(other, sizeof(other), "; %s", s->cause);
        if (want[0])
                return sw_set_cause(s, err < 0 ? err : SYNTHETIC_ERRNO(ENODEV),
                                    "no USB relay board (%04x:%04x) with serial %s (found: %s%s)",
                                    USBRELAY_VID, USBRELAY_PID, want, seen[0] ? seen : "none",
                                    other);
        return sw_set_cause(s, SYNTHETIC_ERRNO(ENODEV), "no USB relay board (%04x:%04x) found",
                            USBRELAY_VID, USBRELAY_PID);
}

/* Keeps candidate c in *f when it is the board wanted (serial want, or any board without),
 * else closes it; the serials seen go into seen. Returns 1 when kept, 0 when not, -ENOTUNIQ
 * for a second board when none is named. */
static int pick(struct found *f, struct found *c, const char *want, char *seen, size_t len)
{
        size_t k = strlen(seen);

        snprintf(seen + k, len - k, "%s%s", k ? ", " : "", c->st.serial);
        if (want[0] ? strcmp(c->st.serial, want) != 0 : f->h != NULL) {
                release(c->h);
                return want[0] ? 0 : -ENOTUNIQ;
        }
        *f = *c;
        return 1;
}

/* Enumerates the relay boards of ctx not in the cache for the one with serial want, or
 * without want the only one. Returns 0 with *f open, or -errno with the cause on s. */
static int scan(struct sw *s, libusb_context *ctx, const char *want, struct found *f)
{
        char seen[64] = "";
        libusb_device **list;
        ssize_t n = libusb_get_device_list(ctx, &list);
        int err = 0, r = 0;

        if (n < 0)
                return sw_set_cause(s, usb_errno((int)n), "cannot list USB devices: %s",
                                    libusb_strerror((int)n));
        *f = (struct found){};
        for (ssize_t i = 0; i < n && r >= 0 && !(want[0] && f->h); i++) {
                struct found c;
                int p = probe(s, list[i], &c);

                if (p < 0)
                        err = p;
                else if (p > 0)
                        r = pick(f, &c, want, seen, sizeof(seen));
        }
        libusb_free_device_list(list, 1);
        if (r == -ENOTUNIQ) {
                release(f->h);
                return sw_set_cause(s, r, "several USB relay boards (%s): name one by serial",
                                    seen);
        }
        return f->h ? 0 : not_found(s, want, seen, err);
}

/* Opens board b: a new context, the board with serial want (or the only one). */
static int open_board(struct usbrelay_board *b, struct sw *s, const char *want)
{
        struct found f;
        int r = libusb_init(&b->ctx);

        if (r < 0) {
                b->ctx = NULL;
                return sw_set_cause(s, usb_errno(r), "libusb: %s", libusb_strerror(r));
        }
        r = scan(s, b->ctx, want, &f);
        if (r < 0) {
                close_handle(b);
                return r;
        }
        b->h = f.h;
        b->relays = f.relays;
        strcpy(b->serial, f.st.serial);
        b->busnum = libusb_get_bus_number(libusb_get_device(f.h));
        b->address = libusb_get_device_address(libusb_get_device(f.h));
        return 0;
}

/* The board of bus with serial, or without serial the bus's only board; NULL if none. */
static struct usbrelay_board *find(const struct bus *bus, const char *serial)
{
        struct usbrelay_board *hit = NULL;
        int n = 0;

        for (struct usbrelay_board *b = cache; b; b = b->next)
                if (b->bus == bus && (!serial[0] || strcmp(b->serial, serial) == 0)) {
                        hit = b;
                        n++;
                }
        return n == 1 ? hit : NULL;
}

/* Opens a new board for s and adds it to the cache. */
static int add(struct sw *s, const char *serial, struct usbrelay_board **ret)
{
        struct usbrelay_board *b = calloc(1, sizeof(*b));
        int r;

        if (!b)
                return -ENOMEM;
        b->bus = s->bus;
        r = open_board(b, s, serial);
        if (r < 0) {
                free(b);
                return r;
        }
        b->next = cache;
        cache = b;
        *ret = b;
        return 0;
}

int usbrelay_board_get(struct sw *s, struct usbrelay_board **ret)
{
        const struct usbrelay_conf *c = s->conf->backend.conf;
        struct usbrelay_board *b;
        int r = 0;

        pthread_mutex_lock(&cache_lock);
        b = find(s->bus, c->serial);
        if (b && !b->h)
                r = open_board(b, s, b->serial); /* replugged? */
        else if (!b)
                r = add(s, c->serial, &b);
        if (r >= 0) {
                b->refs++;
                *ret = b;
        }
        pthread_mutex_unlock(&cache_lock);
        return r;
}

struct usbrelay_board *usbrelay_board_put(struct usbrelay_board *b)
{
        if (!b)
                return NULL;
        pthread_mutex_lock(&cache_lock);
        if (--b->refs == 0) {
                for (struct usbrelay_board **p = &cache; *p; p = &(*p)->next)
                        if (*p == b) {
                                *p = b->next;
                                break;
                        }
                close_handle(b);
                free(b);
        }
        pthread_mutex_unlock(&cache_lock);
        return NULL;
}

bool usbrelay_board_lost(const struct usbrelay_board *b)
{
        return !b->h;
}

int usbrelay_board_relays(const struct usbrelay_board *b)
{
        return b->relays;
}

const char *usbrelay_board_serial(const struct usbrelay_board *b)
{
        return b->serial;
}

/* The board is gone: its handle and context are closed (under the cache lock, which
 * in_cache() reads them under) until fault.clear reopens it. Returns -ENODEV. */
static int lost(struct usbrelay_board *b, struct sw *s, const char *what)
{
        pthread_mutex_lock(&cache_lock);
        close_handle(b);
        pthread_mutex_unlock(&cache_lock);
        return sw_set_cause(s, SYNTHETIC_ERRNO(ENODEV),
                            "USB relay board %s is gone (unplugged?) while %s; fault.clear "
                            "reopens it once it is back",
                            b->serial, what);
}

/* Records a failed transfer (bytes moved n, LIBUSB_ERROR or -EPROTO) on s. */
static int io_error(struct usbrelay_board *b, struct sw *s, int n, const char *what)
{
        if (n == LIBUSB_ERROR_NO_DEVICE)
                return lost(b, s, what);
        if (n == -EPROTO)
                return sw_set_cause(s, n, "USB relay board %s: malformed feature report while %s",
                                    b->serial, what);
        if (n >= 0)
                return sw_set_cause(s, SYNTHETIC_ERRNO(EIO),
                                    "USB relay board %s: %d of %d bytes while %s", b->serial, n,
                                    USBRELAY_REPORT_LEN, what);
        return sw_set_cause(s, usb_errno(n), "USB relay board %s: %s while %s", b->serial,
                            libusb_strerror(n), what);
}

int usbrelay_board_read(struct usbrelay_board *b, struct sw *s, uint8_t *state)
{
        struct usbrelay_status st;
        int r;

        if (!b->h)
                return sw_set_cause(s, SYNTHETIC_ERRNO(ENODEV),
                                    "USB relay board %s was unplugged; fault.clear reopens it "
                                    "once it is back",
                                    b->serial);
        r = get_status(b->h, &st);
        if (r < 0)
                return io_error(b, s, r, "reading the relays");
        *state = st.state;
        return 0;
}

int usbrelay_board_switch(struct usbrelay_board *b, struct sw *s, int relay, bool on,
                          uint8_t *state)
{
        uint8_t rep[USBRELAY_REPORT_LEN];
        int r;

        r = usbrelay_encode(rep, usbrelay_switch_cmd(on), relay, NULL);
        if (r < 0)
                return sw_set_cause(s, r, "relay %d outside 1..%d", relay, USBRELAY_RELAYS_MAX);
        if (!b->h)
                return usbrelay_board_read(b, s, state); /* the unplugged message */
        r = feature_report(b->h, false, rep);
        if (r != USBRELAY_REPORT_LEN)
                return io_error(b, s, r, on ? "switching on" : "switching off");
        return usbrelay_board_read(b, s, state);
}
