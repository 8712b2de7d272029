/* modbus.h - Modbus transactions over a bus's transport (modbus-rtu or modbus-tcp),
 * with the bus's timeout and retry policy; libmodbus stays behind this header.
 *
 * Worker (or sync owner) only. Each call opens the link if needed; a link that cannot
 * be opened (-ENOENT, -EACCES, -EBUSY, ...) fails at once, without retries. A timeout, a
 * corrupt reply (after a flush) or an I/O error (after reopening) is retried up to
 * conf->retries times, each counted and logged (rate-limited); a Modbus exception is an
 * answer and is not retried. The final failure returns -ETIMEDOUT, -EPROTO or -EIO and
 * leaves its cause in transport_cause() ("Connection timed out after 200 ms",
 * "Illegal data address", ...), for the device's own message. */
#pragma once

#include <stdbool.h>
#include <stdint.h>

struct transport;

/* Highest unit address of a Modbus serial line (Modbus over serial line spec, 2.2). */
#define MBUS_UNIT_MAX 247

/* Return the count transferred (>= 0) or -errno, see above. */
int mbus_read_regs(struct transport *t, int unit, int addr, int n, uint16_t *dest);       /* FC03 */
int mbus_write_reg(struct transport *t, int unit, int addr, uint16_t value);              /* FC06 */
int mbus_write_regs(struct transport *t, int unit, int addr, int n, const uint16_t *src); /* FC16 */
int mbus_read_coils(struct transport *t, int unit, int addr, int n, uint8_t *dest);       /* FC01 */
int mbus_write_coil(struct transport *t, int unit, int addr, bool on);                    /* FC05 */

/* Maps the errno left by a failed libmodbus call to -ETIMEDOUT, -EPROTO (exception,
 * bad CRC or frame) or -EIO. Pure. */
int mbus_errno(int err);
