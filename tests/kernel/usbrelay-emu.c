/* usbrelay-emu.c - a USB HID relay board ("USBRelayN", 16c0:05df, www.dcttech.com) emulated in
 * the kernel lane: a configfs USB gadget on dummy_hcd whose one function is this FunctionFS
 * program, answering ep0 as the board's V-USB firmware does:
 *   - HID class GET_REPORT (feature, report 0): 8 bytes, the 5-character serial, two zero bytes,
 *     the relay state bitmask (bit 0 = relay 1);
 *   - HID class SET_REPORT (feature, report 0), 8 bytes: FF n = relay n on, FD n = relay n off
 *     (n outside 1..N ignored), FE = all on, FC = all off, FA s1..s5 = set the serial;
 *   - GET_DESCRIPTOR of the HID report descriptor (vendor page, one 8-byte feature report);
 *   - any other request: acknowledged with no data, as the firmware's usbFunctionSetup does.
 * The state also goes to STATEFILE (one hex byte and a newline) after each change, so tests see
 * the "relay outputs" without asking the emulated board. The seed of gonio's USB relay emulator.
 *
 * Usage: kl-usbrelay-emu [RELAYS [STATEFILE]] (default 2 relays). Returns once the gadget is
 * bound to the first UDC; a child process serves the board until the gadget goes away. */
#include <endian.h> /* le16toh */
#include <fcntl.h>
#include <glob.h>
#include <linux/usb/ch9.h>
#include <linux/usb/functionfs.h>
#include <stdint.h>
#include <sys/mount.h>
#include <sys/stat.h>

#include "common/cleanup.h"
#include "tests/test.h"

#define GADGET  "/sys/kernel/config/usb_gadget/usbrelay"
#define FFS_DIR "/run/usbrelay-ffs"

#define HID_DT_HID           0x21
#define HID_DT_REPORT        0x22
#define HID_REQ_GET_REPORT   0x01
#define HID_REQ_SET_REPORT   0x09
#define HID_REPORT_FEATURE   3
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
        uint8_t all = (uint8_t)((1u << b->relays) - 1);

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
                   rq->bRequest == HID_REQ_GET_REPORT && value == HID_REPORT_FEATURE << 8) {
                memcpy(report, b->serial, SERIAL_LEN);
                report[7] = b->state;
                reply(ep0, report, sizeof(report), length);
        } else {
                reply(ep0, NULL, 0, length);
        }
}

static void handle_out(struct board *b, int ep0, const struct usb_ctrlrequest *rq)
{
        uint16_t value = le16toh(rq->wValue), length = le16toh(rq->wLength);
        uint8_t data[64] = {0};
        ssize_t n = read(ep0, data, length < sizeof(data) ? length : sizeof(data));

        if (n < 0) {
                perror("usbrelay-emu: ep0 data");
                return;
        }
        if ((rq->bRequestType & USB_TYPE_MASK) == USB_TYPE_CLASS &&
            rq->bRequest == HID_REQ_SET_REPORT && value == HID_REPORT_FEATURE << 8 && n >= 2)
                board_command(b, data);
}

/* Serves ep0 events until the function is unbound or ep0 fails. */
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
                        if (ev[i].type == FUNCTIONFS_UNBIND)
                                return;
                        if (ev[i].type != FUNCTIONFS_SETUP)
                                continue;
                        if (ev[i].u.setup.bRequestType & USB_DIR_IN)
                                handle_in(b, ep0, &ev[i].u.setup);
                        else
                                handle_out(b, ep0, &ev[i].u.setup);
                }
        }
}

/* Creates the gadget: the board's ids and strings, one configuration with one FunctionFS
 * function; mounts that function's FunctionFS instance on FFS_DIR. */
static void gadget_create(unsigned relays)
{
        static const char *const dirs[] = {GADGET, GADGET "/strings/0x409", GADGET "/configs/c.1",
                                           GADGET "/functions/ffs.usbrelay"};
        char product[16];

        for (size_t i = 0; i < sizeof(dirs) / sizeof(dirs[0]); i++)
                CHECK(mkdir(dirs[i], 0755) == 0 || errno == EEXIST);
        snprintf(product, sizeof(product), "USBRelay%u", relays);
        CHECK_INT(write_file(GADGET "/idVendor", "0x16c0"), 0);
        CHECK_INT(write_file(GADGET "/idProduct", "0x05df"), 0);
        CHECK_INT(write_file(GADGET "/bcdDevice", "0x0100"), 0);
        CHECK_INT(write_file(GADGET "/strings/0x409/manufacturer", "www.dcttech.com"), 0);
        CHECK_INT(write_file(GADGET "/strings/0x409/product", product), 0);
        CHECK(symlink(GADGET "/functions/ffs.usbrelay", GADGET "/configs/c.1/ffs.usbrelay") == 0 ||
              errno == EEXIST);
        CHECK(mkdir(FFS_DIR, 0755) == 0 || errno == EEXIST);
        CHECK_INT(mount("usbrelay", FFS_DIR, "functionfs", 0, NULL), 0);
}

/* Binds the gadget to the first UDC in /sys/class/udc. */
static void gadget_bind(void)
{
        glob_t g = {0};

        CHECK_INT(glob("/sys/class/udc/*", 0, NULL, &g), 0);
        CHECK_INT(write_file(GADGET "/UDC", strrchr(g.gl_pathv[0], '/') + 1), 0);
        globfree(&g);
}

int main(int argc, char **argv)
{
        struct board b = {.relays = argc > 1 ? (unsigned)atoi(argv[1]) : 2,
                          .serial = {'K', 'L', 'A', 'N', 'E'},
                          .state_file = argc > 2 ? argv[2] : NULL};
        _cleanup_close_ int ep0 = -EBADF;
        pid_t pid;

        CHECK(b.relays >= 1 && b.relays <= 8);
        board_publish(&b);
        gadget_create(b.relays);
        ep0 = open(FFS_DIR "/ep0", O_RDWR | O_CLOEXEC);
        CHECK(ep0 >= 0);
        CHECK(write(ep0, &descriptors, sizeof(descriptors)) == sizeof(descriptors));
        CHECK(write(ep0, &no_strings, sizeof(no_strings)) == sizeof(no_strings));
        gadget_bind();
        fflush(stdout);
        pid = fork();
        CHECK(pid >= 0);
        if (pid > 0) {
                printf("usbrelay-emu: USBRelay%u bound, served by pid %d\n", b.relays, (int)pid);
                return 0;
        }
        serve(&b, ep0);
        return 0;
}
