/* usbrelay-emu.c - a USB HID relay board ("USBRelayN", 16c0:05df, www.dcttech.com) emulated in
 * the kernel lane: a configfs USB gadget on dummy_hcd whose one function is this FunctionFS
 * program, answering ep0 as the board's V-USB firmware does:
 *   - HID class GET_REPORT (whatever wValue asks: the firmware ignores it): 8 bytes, the
 *     5-character serial, two zero bytes, the relay state bitmask (bit 0 = relay 1);
 *   - HID class SET_REPORT (likewise), 8 bytes: FF n = relay n on, FD n = relay n off
 *     (n outside 1..N ignored), FE = all on, FC = all off, FA s1..s5 = set the serial;
 *   - GET_DESCRIPTOR of the HID report descriptor (vendor page, one 8-byte feature report);
 *   - any other request: acknowledged with no data, as the firmware's usbFunctionSetup does.
 * The state also goes to STATEFILE (one hex byte and a newline) after each change, so tests see
 * the "relay outputs" without asking the emulated board. Unbinding the gadget from its UDC
 * unplugs the board: its relays drop (the real board loses power), its serial stays (EEPROM);
 * binding it again plugs it back in, served by the same process.
 *
 * Usage: kl-usbrelay-emu [-n NAME] [-s SERIAL] [-k RELAY]... [RELAYS [STATEFILE]] (default:
 * gadget and FunctionFS instance "usbrelay", serial KLANE, 2 relays; -k injects a fault: that
 * relay is stuck, it ignores every command). Returns once the gadget, bound to
 * the first UDC no other gadget holds, is configured by the host; a child process serves the
 * board until its FunctionFS instance goes away. */
#include <endian.h> /* le16toh */
#include <fcntl.h>
#include <getopt.h>
#include <glob.h>
#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>
#include <stdbool.h>
#include <stdint.h>
#include <sys/mount.h>
#include <sys/stat.h>
#include <time.h>

#include "common/cleanup.h"
#include "tests/test.h"

#define GADGETS "/sys/kernel/config/usb_gadget"

#define HID_DT_HID           0x21
#define HID_DT_REPORT        0x22
#define HID_REQ_GET_REPORT   0x01
#define HID_REQ_SET_REPORT   0x09
#define RELAY_CMD_ON         0xff
#define RELAY_CMD_OFF        0xfd
#define RELAY_CMD_ALL_ON     0xfe
#define RELAY_CMD_ALL_OFF    0xfc
#define RELAY_CMD_SET_SERIAL 0xfa
#define SERIAL_LEN           5

/* USB is little-endian, and so are the lane's amd64 host and guest: descriptors are static
 * initializers, where glibc's () is not a constant expression. */
_Static_assert(__BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__, "descriptors assume a little-endian CPU");

/* The board's report descriptor: vendor page FF00, one feature report of 8 bytes. */
static const uint8_t report_desc[] = {
        0x06, 0x00, 0xff, 0x09, 0x01, 0xa1, 0x01, 0x15, 0x00, 0x26, 0xff,
        0x00, 0x75, 0x08, 0x95, 0x08, 0x09, 0x00, 0xb2, 0x02, 0x01, 0xc0,
};

struct hid_desc {
        uint8_t bLength, bDescriptorType;
        uint16_t bcdHID;
        uint8_t bCountryCode, bNumDescriptors, bClassDescriptorType;
        uint16_t wClassDescriptorLength;
} __attribute__((packed));

struct intf_descs {
        struct usb_interface_descriptor intf;
        struct hid_desc hid;
        struct usb_endpoint_descriptor_no_audio ep;
} __attribute__((packed));

#define INTF_DESCS(interval)                                                                       \
        {                                                                                          \
                .intf = {.bLength = USB_DT_INTERFACE_SIZE,                                         \
                         .bDescriptorType = USB_DT_INTERFACE,                                      \
                         .bNumEndpoints = 1,                                                       \
                         .bInterfaceClass = USB_CLASS_HID},                                        \
                .hid = {.bLength = sizeof(struct hid_desc),                                        \
                        .bDescriptorType = HID_DT_HID,                                             \
                        .bcdHID = (0x0101),                                                        \
                        .bNumDescriptors = 1,                                                      \
                        .bClassDescriptorType = HID_DT_REPORT,                                     \
                        .wClassDescriptorLength = (sizeof(report_desc))},                          \
                .ep = {.bLength = USB_DT_ENDPOINT_SIZE,                                            \
                       .bDescriptorType = USB_DT_ENDPOINT,                                         \
                       .bEndpointAddress = 1 | USB_DIR_IN,                                         \
                       .bmAttributes = USB_ENDPOINT_XFER_INT,                                      \
                       .wMaxPacketSize = (8),                                                      \
                       .bInterval = (interval)},                                                   \
        }

static const struct {
        struct usb_functionfs_descs_head_v2 head;
        uint32_t fs_count, hs_count;
        struct intf_descs fs, hs;
} __attribute__((packed)) descriptors = {
        .head = {.magic = (FUNCTIONFS_DESCRIPTORS_MAGIC_V2),
                 .length = (sizeof(descriptors)),
                 .flags = (FUNCTIONFS_HAS_FS_DESC | FUNCTIONFS_HAS_HS_DESC)},
        .fs_count = (3),
        .hs_count = (3),
        .fs = INTF_DESCS(20),
        .hs = INTF_DESCS(8),
};

static const struct usb_functionfs_strings_head no_strings = {
        .magic = (FUNCTIONFS_STRINGS_MAGIC),
        .length = (sizeof(no_strings)),
};

struct board {
        unsigned relays;
        uint8_t state;
        char serial[SERIAL_LEN];
        const char *state_file;
        const char *name; /* gadget and FunctionFS instance */
        uint8_t stuck;    /* fault injection: relays that ignore every command */
};

static int write_file(const char *path, const char *value)
{
        _cleanup_fclose_ FILE *f = fopen(path, "we");

        if (!f || fputs(value, f) < 0 || fflush(f) != 0)
                return -errno;
        return 0;
}

static void board_publish(const struct board *b)
{
        char line[8];

        if (!b->state_file)
                return;
        snprintf(line, sizeof(line), "%02x\n", b->state);
        CHECK_INT(write_file(b->state_file, line), 0);
}

/* Applies one SET_REPORT feature report, as the firmware does. */
static void board_command(struct board *b, const uint8_t *r)
{
        uint8_t all = (uint8_t)((1u << b->relays) - 1), old = b->state;

        switch (r[0]) {
        case RELAY_CMD_ON:
        case RELAY_CMD_OFF:
                if (r[1] < 1 || r[1] > b->relays)
                        return;
                if (r[0] == RELAY_CMD_ON)
                        b->state |= (uint8_t)(1u << (r[1] - 1));
                else
                        b->state &= (uint8_t) ~(1u << (r[1] - 1));
                break;
        case RELAY_CMD_ALL_ON:
                b->state = all;
                break;
        case RELAY_CMD_ALL_OFF:
                b->state = 0;
                break;
        case RELAY_CMD_SET_SERIAL:
                memcpy(b->serial, r + 1, SERIAL_LEN);
                return;
        default:
                return;
        }
        b->state = (uint8_t)((b->state & ~b->stuck) | (old & b->stuck));
        board_publish(b);
}

/* Answers an IN request: data (possibly none) limited to wLength. */
static void reply(int ep0, const void *data, size_t len, uint16_t wlength)
{
        if (write(ep0, data, len < wlength ? len : wlength) < 0)
                perror("usbrelay-emu: ep0 reply");
}

static void handle_in(struct board *b, int ep0, const struct usb_ctrlrequest *rq)
{
        uint16_t value = le16toh(rq->wValue), length = le16toh(rq->wLength);
        uint8_t report[8] = {0};

        if (rq->bRequest == USB_REQ_GET_DESCRIPTOR && value >> 8 == HID_DT_REPORT) {
                reply(ep0, report_desc, sizeof(report_desc), length);
        } else if (rq->bRequest == USB_REQ_GET_DESCRIPTOR && value >> 8 == HID_DT_HID) {
                reply(ep0, &descriptors.fs.hid, sizeof(descriptors.fs.hid), length);
        } else if ((rq->bRequestType & USB_TYPE_MASK) == USB_TYPE_CLASS &&
                   rq->bRequest == HID_REQ_GET_REPORT) {
                memcpy(report, b->serial, SERIAL_LEN);
                report[7] = b->state;
                reply(ep0, report, sizeof(report), length);
        } else {
                reply(ep0, NULL, 0, length);
        }
}

static void handle_out(struct board *b, int ep0, const struct usb_ctrlrequest *rq)
{
        uint16_t length = le16toh(rq->wLength);
        uint8_t data[64] = {0};
        ssize_t n = read(ep0, data, length < sizeof(data) ? length : sizeof(data));

        if (n < 0) {
                perror("usbrelay-emu: ep0 data");
                return;
        }
        if ((rq->bRequestType & USB_TYPE_MASK) == USB_TYPE_CLASS &&
            rq->bRequest == HID_REQ_SET_REPORT && n >= 2)
                board_command(b, data);
}

/* Serves ep0 events until ep0 fails; an unbind is an unplug (the relays drop). */
static void serve(struct board *b, int ep0)
{
        struct usb_functionfs_event ev[4];

        for (;;) {
                ssize_t n = read(ep0, ev, sizeof(ev));

                if (n < 0 && errno == EINTR)
                        continue;
                if (n <= 0)
                        return;
                for (size_t i = 0; i < (size_t)n / sizeof(ev[0]); i++) {
                        if (ev[i].type == FUNCTIONFS_UNBIND) {
                                b->state = 0;
                                board_publish(b);
                        }
                        if (ev[i].type != FUNCTIONFS_SETUP)
                                continue;
                        if (ev[i].u.setup.bRequestType & USB_DIR_IN)
                                handle_in(b, ep0, &ev[i].u.setup);
                        else
                                handle_out(b, ep0, &ev[i].u.setup);
                }
        }
}

/* Writes value into the file NAME (a printf format with one %s, the gadget's name). */
static void gadget_write(const struct board *b, const char *name, const char *value)
{
        char path[256];

        snprintf(path, sizeof(path), name, b->name);
        CHECK_INT(write_file(path, value), 0);
}

/* Creates the gadget: the board's ids and strings, one configuration with one FunctionFS
 * function; mounts that function's FunctionFS instance on /run/NAME-ffs. */
static void gadget_create(const struct board *b)
{
        static const char *const dirs[] = {GADGETS "/%1$s", GADGETS "/%1$s/strings/0x409",
                                           GADGETS "/%1$s/configs/c.1",
                                           GADGETS "/%1$s/functions/ffs.%1$s", "/run/%1$s-ffs"};
        char path[256], link[256], product[16];

        for (size_t i = 0; i < sizeof(dirs) / sizeof(dirs[0]); i++) {
                snprintf(path, sizeof(path), dirs[i], b->name);
                CHECK(mkdir(path, 0755) == 0 || errno == EEXIST);
        }
        snprintf(product, sizeof(product), "USBRelay%u", b->relays);
        gadget_write(b, GADGETS "/%s/idVendor", "0x16c0");
        gadget_write(b, GADGETS "/%s/idProduct", "0x05df");
        gadget_write(b, GADGETS "/%s/bcdDevice", "0x0100");
        gadget_write(b, GADGETS "/%s/strings/0x409/manufacturer", "www.dcttech.com");
        gadget_write(b, GADGETS "/%s/strings/0x409/product", product);
        snprintf(path, sizeof(path), GADGETS "/%1$s/functions/ffs.%1$s", b->name);
        snprintf(link, sizeof(link), GADGETS "/%1$s/configs/c.1/ffs.%1$s", b->name);
        CHECK(symlink(path, link) == 0 || errno == EEXIST);
        snprintf(path, sizeof(path), "/run/%s-ffs", b->name);
        CHECK_INT(mount(b->name, path, "functionfs", 0, NULL), 0);
}

/* Whether a gadget holds the UDC udc. */
static bool udc_taken(const char *udc)
{
        glob_t g = {0};
        bool taken = false;

        if (glob(GADGETS "/*/UDC", 0, NULL, &g) != 0)
                return false;
        for (size_t i = 0; i < g.gl_pathc && !taken; i++) {
                _cleanup_fclose_ FILE *f = fopen(g.gl_pathv[i], "re");
                char line[64] = "";

                taken = f && fgets(line, sizeof(line), f) && strncmp(line, udc, strlen(udc)) == 0;
        }
        globfree(&g);
        return taken;
}

/* Binds the gadget to the first UDC of /sys/class/udc no other gadget holds; its name goes
 * into udc (64 bytes). */
static void gadget_bind(const struct board *b, char *udc)
{
        glob_t g = {0};
        size_t i;

        CHECK_INT(glob("/sys/class/udc/*", 0, NULL, &g), 0);
        for (i = 0; i < g.gl_pathc && udc_taken(strrchr(g.gl_pathv[i], '/') + 1); i++)
                ;
        CHECK(i < g.gl_pathc);
        snprintf(udc, 64, "%s", strrchr(g.gl_pathv[i], '/') + 1);
        gadget_write(b, GADGETS "/%s/UDC", udc);
        globfree(&g);
}

/* Waits (up to 10 s) until the host has configured the device on udc. */
static void wait_configured(const char *udc)
{
        char path[128], line[32] = "";

        snprintf(path, sizeof(path), "/sys/class/udc/%s/state", udc);
        for (int i = 0; i < 200 && strcmp(line, "configured\n") != 0; i++) {
                _cleanup_fclose_ FILE *f = fopen(path, "re");

                nanosleep(&(struct timespec){.tv_nsec = 50 * 1000 * 1000}, NULL);
                if (!f || !fgets(line, sizeof(line), f))
                        line[0] = '\0';
        }
        CHECK_STR(line, "configured\n");
}

/* Reads the options into b. */
static void parse_args(int argc, char **argv, struct board *b)
{
        int c;

        while ((c = getopt(argc, argv, "n:s:k:")) >= 0) {
                CHECK(c == 'n' || c == 'k' || (c == 's' && strlen(optarg) == SERIAL_LEN));
                if (c == 'n')
                        b->name = optarg;
                else if (c == 's')
                        memcpy(b->serial, optarg, SERIAL_LEN);
                else
                        b->stuck |= (uint8_t)(1u << (atoi(optarg) - 1));
        }
        b->relays = optind < argc ? (unsigned)atoi(argv[optind]) : 2;
        b->state_file = optind + 1 < argc ? argv[optind + 1] : NULL;
        CHECK(b->relays >= 1 && b->relays <= 8);
}

int main(int argc, char **argv)
{
        struct board b = {.serial = {'K', 'L', 'A', 'N', 'E'}, .name = "usbrelay"};
        _cleanup_close_ int ep0 = -EBADF;
        char path[128], udc[64];
        pid_t pid;

        parse_args(argc, argv, &b);
        board_publish(&b);
        gadget_create(&b);
        snprintf(path, sizeof(path), "/run/%s-ffs/ep0", b.name);
        ep0 = open(path, O_RDWR | O_CLOEXEC);
        CHECK(ep0 >= 0);
        CHECK(write(ep0, &descriptors, sizeof(descriptors)) == sizeof(descriptors));
        CHECK(write(ep0, &no_strings, sizeof(no_strings)) == sizeof(no_strings));
        gadget_bind(&b, udc);
        fflush(stdout);
        pid = fork();
        CHECK(pid >= 0);
        if (pid == 0) {
                serve(&b, ep0);
                return 0;
        }
        wait_configured(udc);
        printf("usbrelay-emu: %s: USBRelay%u %.5s on %s, served by pid %d\n", b.name, b.relays,
               b.serial, udc, (int)pid);
        return 0;
}
