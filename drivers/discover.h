/* discover.h - what a rig file could name on this machine: serial ports, V4L2 nodes,
 * gpiochips and USB devices (HID relay boards marked), found in sysfs without opening
 * any device, so an operator can write a rig file before goniod runs (`gonioctl
 * devices`). The families are a table (discover.c); backends may add richer ones. */
#pragma once

#include <jansson.h>

/* Lists the devices below sysfs (normally "/sys") as {"serial": [...], "v4l2": [...],
 * "gpio": [...], "usb": [...]} (docs/gonioctl.md, "devices"). A family whose folder is
 * missing gives an empty list. New reference, or NULL without memory. */
json_t *discover_all(const char *sysfs);
