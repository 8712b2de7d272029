/* board.h - the "usbrelay" backend's boards: one libusb handle per board and bus, shared
 * by every switch on that board (a per-bus cache keyed by serial), opened by vid:pid, product
 * string and serial. Called on the bus worker of the switch (or its sync owner). */
#pragma once

#include <stdbool.h>
#include <stdint.h>

#include "drivers/switch/switch.h"

struct usbrelay_board;

/* The board of switch s (its bus, the serial of its rig-file map or, without one, the bus's
 * only board), opened on first use, with one more reference. A board that was unplugged is
 * reopened. On failure records the cause with sw_set_cause(). Returns 0, -ENODEV (no such
 * board), -ENOTUNIQ (several boards, no serial), -EBUSY or another -errno. */
int usbrelay_board_get(struct sw *s, struct usbrelay_board **ret);

/* Drops a reference; the last one closes the board. NULL is a no-op. Returns NULL. */
struct usbrelay_board *usbrelay_board_put(struct usbrelay_board *b);

/* Whether the board's handle was lost (unplugged) since it was opened. */
bool usbrelay_board_lost(const struct usbrelay_board *b);

/* The relay count, from the product string. */
int usbrelay_board_relays(const struct usbrelay_board *b);

/* The board's serial, as its feature report gives it. */
const char *usbrelay_board_serial(const struct usbrelay_board *b);

/* Reads the relay bitmask (GET_REPORT). Records the cause on s; -ENODEV once unplugged. */
int usbrelay_board_read(struct usbrelay_board *b, struct sw *s, uint8_t *state);

/* Switches relay on or off (SET_REPORT) and reads the bitmask back into *state. Records the
 * cause on s. Returns 0 or -errno. */
int usbrelay_board_switch(struct usbrelay_board *b, struct sw *s, int relay, bool on,
                          uint8_t *state);
