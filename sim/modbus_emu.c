/* modbus_emu.c - emulated Modbus controllers of gonio-sim: axis drives of the
 * register profiles of docs/modbus-profile.md (the generic family of the rig file's
 * profiles and "gonio-default", and Oriental Motor's AZ series, "azd") and relay modules,
 * served by the real libmodbus on pseudo-terminals (RTU) or loopback TCP. The drive
 * physics live in drive.c and the pty setup in pty.c; this file maps registers and coils
 * onto them and frames the requests.
 *
 * DESIGN
 * - One thread per Modbus bus serves every unit on it. A libmodbus RTU server
 *   only answers its own slave id, so the thread frames each request itself
 *   (RTU: slave + function code give the length, CRC16 checked here; TCP: the
 *   MBAP header gives it), looks the unit up and lets modbus_reply() build the
 *   answer from that unit's mapping. Unknown units get no answer, as on a real bus.
 * - libmodbus writes its replies into one end of a socketpair; the thread moves
 *   them to the pty or TCP client, which is where a CRC fault corrupts them.
 * - Device state (drives, registers, coils) is guarded by one mutex, shared with
 *   sim_emu_snapshot() on the frame server's thread. Axis registers are refreshed
 *   from the drive model right before each reply; commands take
 *   effect right after the reply that accepted them. Each profile family has its
 *   own register mapping (struct emu_family) over the one drive model, so both
 *   families move with the same timing.
 * - Emulated time is CLOCK_MONOTONIC since creation times time_scale.
 * - The threads poll with a short timeout and check the stop flag, so
 *   sim_emu_free() returns promptly. */
#include <errno.h>
#include <math.h>
#include <poll.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include <modbus/modbus.h>
#include <netinet/in.h>

#include "common/clock.h"
#include "common/log.h"
#include "drivers/axis/modbus/proto.h"
#include "drivers/switch/modbus/proto.h"
#include "sim/drive.h"
#include "sim/gcode_emu.h"
#include "sim/modbus_emu.h"
#include "sim/pty.h"

#define EMU_MAX_UNITS     (RIG_MAX_AXES + RIG_MAX_LAMPS + 1)
#define EMU_MAX_CONNS     4
#define EMU_POLL_MS       50  /* stop-flag latency */
#define EMU_BYTE_TIMEOUT  100 /* ms between bytes of one request before it is dropped */
#define EMU_WRITE_TIMEOUT 1000
#define EMU_ADU_MAX       MODBUS_TCP_MAX_ADU_LENGTH

struct emu_axis {
        struct sim_drive drive;
        const struct mbax_conf *conf; /* unit, family, profile: borrowed from the rig config */
        const struct emu_family *fam;
        uint16_t inputs; /* azd: the driver input command (lower word) as last written */
};

struct emu_unit {
        int bus; /* index into rc->buses */
        int id;  /* Modbus unit id */
        bool is_axis;
        struct emu_axis axis;
        int n_coils;
        modbus_mapping_t *map;
        enum sim_fault fault;
};

struct emu_bus {
        struct sim_emu *emu;
        int index;
        const struct rig_bus_conf *conf;
        modbus_t *ctx;
        int reply[2];       /* socketpair: libmodbus writes into [0], we read [1] */
        struct sim_pty pty; /* RTU */
        int listen_fd;      /* TCP */
        int tcp_port;
        int conns[EMU_MAX_CONNS];
        atomic_int unplug_ms; /* > 0: the thread unplugs the line for that long */
        pthread_t thread;
        bool started;
};

struct sim_emu {
        const struct rig_config *rc;
        double time_scale;
        uint64_t epoch_ns; /* CLOCK_MONOTONIC at start */
        atomic_bool stop;
        pthread_mutex_t lock; /* guards units[] and their mappings */
        struct emu_unit units[EMU_MAX_UNITS];
        size_t n_units;
        struct emu_bus buses[RIG_MAX_BUSES];
        size_t n_buses;
        struct sim_gcode *gcode; /* the serial G-code controllers (gcode_emu.c) */
};

/* ---- time, encoding ---- */

static double emu_now(const struct sim_emu *e)
{
        return (double)(gn_monotonic_ns() - e->epoch_ns) * 1e-9 * e->time_scale;
}

static uint16_t crc16(const uint8_t *p, size_t n)
{
        uint16_t crc = 0xFFFF;

        for (size_t i = 0; i < n; i++) {
                crc ^= p[i];
                for (int b = 0; b < 8; b++)
                        crc = (crc & 1) ? (crc >> 1) ^ 0xA001 : crc >> 1;
        }
        return crc;
}

static uint16_t be16(const uint8_t *p)
{
        return (uint16_t)(p[0] << 8 | p[1]);
}

static void put_u32(uint16_t *regs, uint16_t addr, bool swap, uint32_t u)
{
        regs[addr + (swap ? 1 : 0)] = (uint16_t)(u >> 16);
        regs[addr + (swap ? 0 : 1)] = (uint16_t)u;
}

static int32_t get_i32(const uint16_t *regs, uint16_t addr, bool swap)
{
        uint32_t hi = regs[addr + (swap ? 1 : 0)], lo = regs[addr + (swap ? 0 : 1)];
        return (int32_t)(hi << 16 | lo);
}

/* ---- axis drive registers ---- */

/* How a register-map family of drives is emulated: its registers (span, refresh before
 * each reply) and what a request does (check before the reply: a Modbus exception or 0;
 * execute after it). */
struct emu_family {
        const struct mbax_family *family;
        int (*span)(const struct emu_axis *a);
        void (*refresh)(struct emu_axis *a, modbus_mapping_t *map, double now);
        int (*check)(struct emu_axis *a, const modbus_mapping_t *map, const uint8_t *req, int len,
                     int off, double now);
        void (*execute)(struct emu_axis *a, modbus_mapping_t *map, const uint8_t *req, int len,
                        int off, double now);
};

/* The value a write request (at PDU offset off) puts into register reg, or -1. */
static int written_value(uint16_t reg, const uint8_t *req, int len, int off)
{
        uint16_t addr = be16(req + off + 1);

        if (req[off] == MODBUS_FC_WRITE_SINGLE_REGISTER && len >= off + 5)
                return addr == reg ? be16(req + off + 3) : -1;
        if (req[off] != MODBUS_FC_WRITE_MULTIPLE_REGISTERS || len < off + 6)
                return -1;
        uint16_t nb = be16(req + off + 3);
        int at = off + 6 + 2 * (reg - addr);
        if (reg < addr || reg >= addr + nb || at + 2 > len)
                return -1;
        return be16(req + at);
}

/* The drive's position at now in counts of the axis's scale. */
static uint32_t position_counts(struct emu_axis *a, double now)
{
        return (uint32_t)llround(sim_drive_position(&a->drive, now) * a->conf->scale);
}

/* -- generic: a rig_modbus_profile's registers, commands in one register -- */

static int generic_span(const struct emu_axis *a)
{
        const struct rig_modbus_profile *p = a->conf->profile;
        int n = MAX(p->reg_status, p->reg_fault) + 1;

        n = MAX(n, MAX(p->reg_position, p->reg_target) + 2);
        return MAX(n, MAX(p->reg_speed, MAX(p->reg_accel, p->reg_command)) + 1);
}

static void generic_refresh(struct emu_axis *a, modbus_mapping_t *map, double now)
{
        const struct rig_modbus_profile *p = a->conf->profile;
        struct sim_drive_status st = sim_drive_status(&a->drive, now);

        map->tab_registers[p->reg_status] =
                (uint16_t)(1u << 0 | (unsigned)st.homed << 1 | (unsigned)st.moving << 2 |
                           (unsigned)st.in_position << 3 | (unsigned)st.fault << 4 |
                           (unsigned)st.home_switch << 5);
        map->tab_registers[p->reg_fault] = (uint16_t)a->drive.fault_code;
        put_u32(map->tab_registers, p->reg_position, p->word_swap, position_counts(a, now));
}

static double reg_speed(const struct emu_axis *a, const modbus_mapping_t *map)
{
        return map->tab_registers[a->conf->profile->reg_speed] / 10.0;
}

static double reg_accel(const struct emu_axis *a, const modbus_mapping_t *map)
{
        return map->tab_registers[a->conf->profile->reg_accel] / 10.0;
}

/* Modbus exception for the command a request writes, or 0 when the drive accepts it (or
 * it writes none). */
static int generic_check(struct emu_axis *a, const modbus_mapping_t *map, const uint8_t *req,
                         int len, int off, double now)
{
        const struct rig_modbus_profile *p = a->conf->profile;
        int cmd = written_value(p->reg_command, req, len, off);

        if (cmd < 0 || cmd == p->cmd_stop || cmd == p->cmd_reset)
                return 0;
        if (cmd == p->cmd_move || cmd == p->cmd_home) {
                int r = sim_drive_check_move(&a->drive, now, reg_speed(a, map), reg_accel(a, map));
                return r == -EIO      ? MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE
                       : r == -EINVAL ? MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE
                                      : 0;
        }
        return MODBUS_EXCEPTION_ILLEGAL_DATA_VALUE;
}

static void generic_execute(struct emu_axis *a, modbus_mapping_t *map, const uint8_t *req, int len,
                            int off, double now)
{
        const struct rig_modbus_profile *p = a->conf->profile;
        int cmd = written_value(p->reg_command, req, len, off);
        double v = reg_speed(a, map), acc = reg_accel(a, map);

        if (cmd < 0)
                return;
        /* Checked by generic_check before the reply. */
        if (cmd == p->cmd_move)
                (void)sim_drive_move(&a->drive, now,
                                     get_i32(map->tab_registers, p->reg_target, p->word_swap) /
                                             a->conf->scale,
                                     v, acc);
        else if (cmd == p->cmd_home)
                (void)sim_drive_home(&a->drive, now, v, acc);
        else if (cmd == p->cmd_stop)
                sim_drive_stop(&a->drive, now);
        else if (cmd == p->cmd_reset)
                sim_drive_reset(&a->drive);
        map->tab_registers[p->reg_command] = 0;
}

/* -- azd: Oriental Motor AZ series (drivers/axis/modbus/azd.c) -- */

static int azd_span(const struct emu_axis *a)
{
        (void)a;
        return AZD_REG_FEEDBACK_POS + 2;
}

static void azd_refresh(struct emu_axis *a, modbus_mapping_t *map, double now)
{
        struct sim_drive_status st = sim_drive_status(&a->drive, now);
        uint16_t *regs = map->tab_registers;

        put_u32(regs, AZD_REG_OUTPUT, false,
                (st.homed ? AZD_OUT_HOME_END : 0) | (!st.moving && !st.fault ? AZD_OUT_READY : 0) |
                        (st.fault ? AZD_OUT_ALM_A : 0) | (st.moving ? AZD_OUT_MOVE : 0) |
                        (st.in_position ? AZD_OUT_IN_POS : 0));
        put_u32(regs, AZD_REG_ALARM, false,
                a->drive.fault_code == SIM_DRIVE_FAULT_STALL ? AZD_ALARM_DEVIATION
                                                             : (uint32_t)a->drive.fault_code);
        put_u32(regs, AZD_REG_FEEDBACK_POS, false, position_counts(a, now));
}

static int azd_check(struct emu_axis *a, const modbus_mapping_t *map, const uint8_t *req, int len,
                     int off, double now)
{
        (void)a, (void)map, (void)req, (void)len, (void)off, (void)now;
        return 0; /* the AZ takes the data; a move during an alarm starts nothing */
}

/* A direct data operation whose trigger a request set to 1: an absolute positioning at the
 * block's speed and starting rate starts (not during an alarm), and the trigger returns
 * to 0. Other operation types are not emulated. */
static void azd_direct(struct emu_axis *a, uint16_t *regs, double now)
{
        double s = a->conf->scale;

        if (get_i32(regs, AZD_REG_DIRECT_TRIG, false) != 1)
                return;
        put_u32(regs, AZD_REG_DIRECT_TRIG, false, 0);
        if (get_i32(regs, AZD_REG_DIRECT + 2, false) != AZD_OP_ABSOLUTE) {
                log_warning("axis '%s': direct data operation type %d is not emulated",
                            a->drive.conf->name, get_i32(regs, AZD_REG_DIRECT + 2, false));
                return;
        }
        (void)sim_drive_move(&a->drive, now, get_i32(regs, AZD_REG_DIRECT + 4, false) / s,
                             get_i32(regs, AZD_REG_DIRECT + 6, false) / s,
                             get_i32(regs, AZD_REG_DIRECT + 8, false) / s);
}

/* Rising edges of the driver input command: ZHOME homes (at the axis's max_speed and accel,
 * as the drive's return-to-home parameters), STOP stops, ALM-RST clears the alarm. */
static void azd_inputs(struct emu_axis *a, uint16_t in, double now)
{
        uint16_t rising = in & (uint16_t)~a->inputs;

        a->inputs = in;
        if (rising & AZD_IN_STOP)
                sim_drive_stop(&a->drive, now);
        if (rising & AZD_IN_ALM_RST)
                sim_drive_reset(&a->drive);
        if (rising & AZD_IN_ZHOME)
                (void)sim_drive_home(&a->drive, now, a->drive.conf->max_speed,
                                     a->drive.conf->accel);
}

static void azd_execute(struct emu_axis *a, modbus_mapping_t *map, const uint8_t *req, int len,
                        int off, double now)
{
        int in = written_value(AZD_REG_INPUT + 1, req, len, off);

        if (written_value(AZD_REG_DIRECT_TRIG + 1, req, len, off) >= 0)
                azd_direct(a, map->tab_registers, now);
        if (in >= 0)
                azd_inputs(a, (uint16_t)in, now);
}

static const struct emu_family emu_families[] = {
        {&mbax_generic, generic_span, generic_refresh, generic_check, generic_execute},
        {&mbax_azd, azd_span, azd_refresh, azd_check, azd_execute},
};

static int axis_reply(struct emu_unit *u, modbus_t *ctx, const uint8_t *req, int len, int off,
                      double now)
{
        struct emu_axis *a = &u->axis;

        a->fam->refresh(a, u->map, now);
        int exc = a->fam->check(a, u->map, req, len, off, now);
        if (exc)
                return modbus_reply_exception(ctx, req, (unsigned)exc);
        int r = modbus_reply(ctx, req, len, u->map);
        if (r >= 0) {
                a->fam->execute(a, u->map, req, len, off, now);
                a->fam->refresh(a, u->map, now);
        }
        return r;
}

/* ---- lookups ---- */

static bool is_modbus(enum rig_bus_type t)
{
        return t == RIG_BUS_MODBUS_RTU || t == RIG_BUS_MODBUS_TCP;
}

static int bus_index(const struct sim_emu *e, const char *name)
{
        const struct rig_bus_conf *b = rigconf_bus(e->rc, name);
        return b ? (int)(b - e->rc->buses) : -ENOENT;
}

static struct emu_unit *find_unit(struct sim_emu *e, int bus, int id)
{
        for (size_t i = 0; i < e->n_units; i++)
                if (e->units[i].bus == bus && e->units[i].id == id)
                        return &e->units[i];
        return NULL;
}

static const struct emu_bus *find_bus(const struct sim_emu *e, const char *name)
{
        for (size_t i = 0; i < e->n_buses; i++)
                if (strcmp(e->buses[i].conf->name, name) == 0)
                        return &e->buses[i];
        return NULL;
}

/* ---- byte I/O ---- */

/* Waits up to timeout_ms for fd to be readable, then reads at most n bytes.
 * Returns the count, -ETIMEDOUT, -ECONNRESET at end of file, or -errno. */
static int read_some(int fd, uint8_t *buf, size_t n, int timeout_ms)
{
        struct pollfd p = {.fd = fd, .events = POLLIN};

        int r = poll(&p, 1, timeout_ms);
        if (r < 0)
                return errno == EINTR ? -ETIMEDOUT : -errno;
        if (r == 0)
                return -ETIMEDOUT;
        ssize_t k = read(fd, buf, n);
        if (k < 0)
                return errno == EAGAIN || errno == EINTR ? -ETIMEDOUT : -errno;
        return k == 0 ? -ECONNRESET : (int)k;
}

/* Reads exactly n bytes, waiting at most timeout_ms for each chunk. Returns 0 or -errno. */
static int read_exact(int fd, uint8_t *buf, size_t n, int timeout_ms)
{
        while (n > 0) {
                int r = read_some(fd, buf, n, timeout_ms);
                if (r < 0)
                        return r;
                buf += r;
                n -= (size_t)r;
        }
        return 0;
}

/* Writes all of buf (send() without SIGPIPE on sockets), waiting for room at most
 * EMU_WRITE_TIMEOUT ms at a time. Returns 0 or -errno. */
static int write_all(int fd, bool sock, const uint8_t *buf, size_t n)
{
        while (n > 0) {
                ssize_t k = sock ? send(fd, buf, n, MSG_NOSIGNAL) : write(fd, buf, n);
                if (k < 0 && errno != EAGAIN && errno != EINTR)
                        return -errno;
                if (k < 0) {
                        struct pollfd p = {.fd = fd, .events = POLLOUT};
                        if (poll(&p, 1, EMU_WRITE_TIMEOUT) == 0)
                                return -ETIMEDOUT;
                        continue;
                }
                buf += k;
                n -= (size_t)k;
        }
        return 0;
}

/* Discards input until the line has been quiet for a while (resynchronises framing). */
static void drain(int fd)
{
        uint8_t junk[256];

        for (int i = 0; i < 64 && read_some(fd, junk, sizeof junk, 20) > 0; i++)
                ;
}

/* ---- framing ---- */

/* Length of the RTU request (with CRC) whose first have >= 2 bytes are in b, as far as
 * those bytes tell, or -EBADMSG for a function code that cannot be sized. */
static int rtu_request_length(const uint8_t *b, size_t have)
{
        switch (b[1]) {
        case 0x01 ... 0x06:
                return 8;
        case 0x07:
        case 0x0B:
        case 0x0C:
        case 0x11:
                return 4;
        case 0x16:
                return 10;
        case 0x0F:
        case 0x10:
                return have < 7 ? 7 : 9 + b[6];
        case 0x17:
                return have < 11 ? 11 : 13 + b[10];
        default:
                return -EBADMSG;
        }
}

/* Reads one RTU request. Returns its length, -ETIMEDOUT when the line is idle or a
 * frame stopped short, -EBADMSG for an unframeable request, or -errno. */
static int rtu_read_frame(int fd, uint8_t *buf)
{
        int r = read_some(fd, buf, 1, EMU_POLL_MS);
        if (r < 0)
                return r;

        size_t have = 1;
        for (;;) {
                int need = have < 2 ? 2 : rtu_request_length(buf, have);
                if (need < 0 || need > MODBUS_RTU_MAX_ADU_LENGTH)
                        return -EBADMSG;
                if ((size_t)need == have)
                        return need;
                r = read_exact(fd, buf + have, (size_t)need - have, EMU_BYTE_TIMEOUT);
                if (r < 0)
                        return r;
                have = (size_t)need;
        }
}

/* Reads one Modbus TCP request (MBAP header + PDU). Returns its length or -errno. */
static int tcp_read_frame(int fd, uint8_t *buf)
{
        int r = read_exact(fd, buf, 7, EMU_BYTE_TIMEOUT);
        if (r < 0)
                return r;
        uint16_t len = be16(buf + 4);
        if (be16(buf + 2) != 0 || len < 2 || 6 + len > EMU_ADU_MAX)
                return -EBADMSG;
        r = read_exact(fd, buf + 7, len - 1u, EMU_BYTE_TIMEOUT);
        return r < 0 ? r : 6 + len;
}

/* ---- serving ---- */

/* Moves the n-byte reply libmodbus wrote into the socketpair to out, corrupting it on
 * request (RTU: the CRC; TCP, which has none: the transaction id). */
static void forward_reply(struct emu_bus *b, int out, int n, bool corrupt)
{
        bool tcp = b->conf->type == RIG_BUS_MODBUS_TCP;
        uint8_t rsp[EMU_ADU_MAX];

        int r = n <= (int)sizeof rsp ? read_exact(b->reply[1], rsp, (size_t)n, EMU_BYTE_TIMEOUT)
                                     : -EMSGSIZE;
        if (r >= 0 && corrupt)
                rsp[tcp ? 0 : n - 1] ^= 0xA5;
        if (r >= 0)
                r = write_all(out, tcp, rsp, (size_t)n);
        if (r < 0)
                log_warning_errno(r, "bus '%s': failed to send reply: %m", b->conf->name);
}

static void serve_request(struct emu_bus *b, int out, const uint8_t *req, int len, int unit)
{
        struct sim_emu *e = b->emu;
        int off = b->conf->type == RIG_BUS_MODBUS_TCP ? 7 : 1, r = 0;

        pthread_mutex_lock(&e->lock);
        struct emu_unit *u = find_unit(e, b->index, unit);
        enum sim_fault f = u ? u->fault : SIM_FAULT_TIMEOUT; /* unknown unit: silence */
        if (f != SIM_FAULT_TIMEOUT) {
                modbus_set_slave(b->ctx, unit);
                if (f == SIM_FAULT_EXCEPTION)
                        r = modbus_reply_exception(b->ctx, req,
                                                   MODBUS_EXCEPTION_SLAVE_OR_SERVER_FAILURE);
                else if (u->is_axis)
                        r = axis_reply(u, b->ctx, req, len, off, emu_now(e));
                else
                        r = modbus_reply(b->ctx, req, len, u->map);
        }
        pthread_mutex_unlock(&e->lock);

        if (r < 0)
                log_warning("bus '%s' unit %d: no reply: %s", b->conf->name, unit,
                            modbus_strerror(errno));
        else if (r > 0)
                forward_reply(b, out, r, f == SIM_FAULT_CRC);
}

static void rtu_serve(struct emu_bus *b)
{
        uint8_t req[EMU_ADU_MAX];

        int n = rtu_read_frame(b->pty.master, req);
        if (n == -ETIMEDOUT)
                return;
        if (n < 0) {
                log_debug_errno(n, "bus '%s': unframeable request dropped: %m", b->conf->name);
                drain(b->pty.master);
                return;
        }
        if (crc16(req, (size_t)n - 2) != (req[n - 2] | req[n - 1] << 8)) {
                log_debug("bus '%s': request with bad CRC dropped", b->conf->name);
                return;
        }
        serve_request(b, b->pty.master, req, n, req[0]);
}

static void tcp_accept(struct emu_bus *b)
{
        int fd = accept4(b->listen_fd, NULL, NULL, SOCK_CLOEXEC);
        if (fd < 0)
                return;
        for (int i = 0; i < EMU_MAX_CONNS; i++)
                if (b->conns[i] < 0) {
                        b->conns[i] = fd;
                        return;
                }
        log_warning("bus '%s': more than %d clients, refused", b->conf->name, EMU_MAX_CONNS);
        close(fd);
}

static void tcp_serve(struct emu_bus *b)
{
        struct pollfd p[1 + EMU_MAX_CONNS] = {{.fd = b->listen_fd, .events = POLLIN}};
        uint8_t req[EMU_ADU_MAX];

        for (int i = 0; i < EMU_MAX_CONNS; i++)
                p[1 + i] = (struct pollfd){.fd = b->conns[i], .events = POLLIN};
        if (poll(p, ELEMENTSOF(p), EMU_POLL_MS) <= 0)
                return;
        if (p[0].revents)
                tcp_accept(b);
        for (int i = 0; i < EMU_MAX_CONNS; i++) {
                if (!p[1 + i].revents || b->conns[i] < 0)
                        continue;
                int n = tcp_read_frame(b->conns[i], req);
                if (n < 0) {
                        close(b->conns[i]);
                        b->conns[i] = -1;
                        continue;
                }
                serve_request(b, b->conns[i], req, n, req[6]);
        }
}

/* The line is pulled out for ms: its pty and symlink go, then come back at the same path
 * (a new pty, as a replugged adapter gets a new tty). The bus thread does it, so no request
 * is being served meanwhile. */
static void rtu_unplug(struct emu_bus *b, int ms)
{
        char who[RIG_NAME_MAX + 8];
        uint64_t end = gn_monotonic_ns() + (uint64_t)ms * 1000000u;

        log_info("bus '%s': unplugged for %d ms", b->conf->name, ms);
        sim_pty_close(&b->pty);
        while (gn_monotonic_ns() < end && !atomic_load(&b->emu->stop))
                usleep(10 * 1000);
        snprintf(who, sizeof who, "bus '%s'", b->conf->name);
        if (sim_pty_open(&b->pty, b->conf->port, who) < 0)
                log_error("bus '%s': cannot plug the line back in", b->conf->name);
        else
                log_info("bus '%s': plugged back in at %s", b->conf->name, b->pty.path);
        atomic_store(&b->unplug_ms, 0);
}

static void *bus_thread(void *userdata)
{
        struct emu_bus *b = userdata;

        while (!atomic_load(&b->emu->stop)) {
                int ms = atomic_load(&b->unplug_ms);
                if (ms > 0)
                        rtu_unplug(b, ms);
                else if (b->conf->type == RIG_BUS_MODBUS_TCP)
                        tcp_serve(b);
                else if (b->pty.master >= 0)
                        rtu_serve(b);
                else
                        usleep(EMU_POLL_MS * 1000);
        }
        return NULL;
}

/* ---- setup ---- */

static int bus_open_rtu(struct emu_bus *b)
{
        const struct rig_bus_conf *c = b->conf;

        char who[RIG_NAME_MAX + 8];

        snprintf(who, sizeof who, "bus '%s'", c->name);
        int r = sim_pty_open(&b->pty, c->port, who);
        if (r < 0)
                return r;
        b->ctx = modbus_new_rtu(b->pty.path, c->baud > 0 ? c->baud : 115200,
                                c->parity ? c->parity : 'N', c->data_bits > 0 ? c->data_bits : 8,
                                c->stop_bits > 0 ? c->stop_bits : 1);
        if (!b->ctx)
                return log_error_errno(errno, "bus '%s': modbus_new_rtu: %m", c->name);
        return 0;
}

static int bus_open_tcp(struct emu_bus *b)
{
        struct sockaddr_in sa;
        socklen_t sl = sizeof sa;

        b->ctx = modbus_new_tcp("127.0.0.1", b->conf->tcp_port);
        if (!b->ctx)
                return log_error_errno(errno, "bus '%s': modbus_new_tcp: %m", b->conf->name);
        b->listen_fd = modbus_tcp_listen(b->ctx, EMU_MAX_CONNS);
        if (b->listen_fd < 0 || getsockname(b->listen_fd, (struct sockaddr *)&sa, &sl) < 0)
                return log_error_errno(errno, "bus '%s': cannot listen on 127.0.0.1:%d: %m",
                                       b->conf->name, b->conf->tcp_port);
        b->tcp_port = ntohs(sa.sin_port);
        return 0;
}

static int bus_start(struct sim_emu *e, int index)
{
        struct emu_bus *b = &e->buses[e->n_buses++]; /* counted now: sim_emu_free cleans up */

        *b = (struct emu_bus){.emu = e,
                              .index = index,
                              .conf = &e->rc->buses[index],
                              .reply = {-1, -1},
                              .pty = SIM_PTY_NULL,
                              .listen_fd = -1};
        for (int i = 0; i < EMU_MAX_CONNS; i++)
                b->conns[i] = -1;
        int r = b->conf->type == RIG_BUS_MODBUS_TCP ? bus_open_tcp(b) : bus_open_rtu(b);
        if (r < 0)
                return r;
        if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, b->reply) < 0)
                return log_error_errno(errno, "socketpair: %m");
        modbus_set_socket(b->ctx, b->reply[0]);
        r = -pthread_create(&b->thread, NULL, bus_thread, b);
        if (r < 0)
                return log_error_errno(r, "bus '%s': cannot start thread: %m", b->conf->name);
        b->started = true;
        return 0;
}

static void close_fd(int fd)
{
        if (fd >= 0)
                close(fd);
}

static void bus_stop(struct emu_bus *b)
{
        if (b->started)
                pthread_join(b->thread, NULL);
        if (b->ctx)
                modbus_free(b->ctx);
        for (int i = 0; i < EMU_MAX_CONNS; i++)
                close_fd(b->conns[i]);
        close_fd(b->listen_fd);
        close_fd(b->reply[0]);
        close_fd(b->reply[1]);
        sim_pty_close(&b->pty);
}

/* The unit id on bus for device dev, created on first use. Two devices may share a unit
 * only as coils of one relay module. */
static int add_unit(struct sim_emu *e, const char *bus, int id, bool axis, const char *dev,
                    struct emu_unit **ret)
{
        int bi = bus_index(e, bus);
        if (bi < 0 || !is_modbus(e->rc->buses[bi].type))
                return log_error_errno(SYNTHETIC_ERRNO(EINVAL),
                                       "'%s': bus '%s' is not a Modbus bus of the rig", dev, bus);
        struct emu_unit *u = find_unit(e, bi, id);
        if (u && (axis || u->is_axis))
                return log_error_errno(SYNTHETIC_ERRNO(EINVAL),
                                       "'%s': unit %d on bus '%s' is already taken", dev, id, bus);
        if (!u) {
                if (e->n_units >= EMU_MAX_UNITS)
                        return log_error_errno(SYNTHETIC_ERRNO(E2BIG), "too many Modbus units");
                u = &e->units[e->n_units++];
                *u = (struct emu_unit){.bus = bi, .id = id, .is_axis = axis};
        }
        *ret = u;
        return 0;
}

static uint16_t reg_tenths(double v)
{
        return (uint16_t)CLAMP(llround(v * 10.0), 1, 65535);
}

/* An axis of the "modbus" backend: its unit and profile as the rig file gave them. */
static int add_axis(struct sim_emu *e, const struct rig_axis_conf *c)
{
        const struct mbax_conf *mc = c->backend.conf;
        struct emu_unit *u;
        int r = add_unit(e, c->bus, mc->unit, true, c->name, &u);
        if (r < 0)
                return r;

        struct emu_axis *a = &u->axis;
        a->conf = mc;
        for (size_t i = 0; i < ELEMENTSOF(emu_families); i++)
                if (emu_families[i].family == mc->family)
                        a->fam = &emu_families[i];
        if (!a->fam)
                return log_error_errno(SYNTHETIC_ERRNO(EOPNOTSUPP),
                                       "axis '%s': profile family '%s' is not emulated", c->name,
                                       mc->family->name);
        sim_drive_init(&a->drive, c);

        u->map = modbus_mapping_new(0, 0, a->fam->span(a), 0);
        if (!u->map)
                return log_error_errno(errno, "axis '%s': %m", c->name);
        if (mc->profile) { /* the generic family's rate registers */
                u->map->tab_registers[mc->profile->reg_speed] = reg_tenths(c->max_speed);
                u->map->tab_registers[mc->profile->reg_accel] = reg_tenths(c->accel);
        }
        return 0;
}

/* A switch of the "modbus-coil" backend. */
static int add_coil(struct sim_emu *e, const struct rig_switch_conf *c)
{
        const struct mbsw_conf *mc = c->backend.conf;
        struct emu_unit *u;
        int r = add_unit(e, c->bus, mc->unit, false, c->name, &u);
        if (r < 0)
                return r;
        u->n_coils = MAX(u->n_coils, mc->coil + 1);
        return 0;
}

static int add_devices(struct sim_emu *e)
{
        const struct rig_config *rc = e->rc;
        int r = 0;

        for (size_t i = 0; r >= 0 && i < rc->n_axes; i++)
                if (strcmp(rc->axes[i].backend.name, "modbus") == 0)
                        r = add_axis(e, &rc->axes[i]);
        for (size_t i = 0; r >= 0 && i < rc->n_lamps; i++)
                if (strcmp(rc->lamps[i].backend.name, "modbus-coil") == 0)
                        r = add_coil(e, &rc->lamps[i]);
        for (size_t i = 0; r >= 0 && i < rc->n_lasers; i++)
                if (strcmp(rc->lasers[i].backend.name, "modbus-coil") == 0)
                        r = add_coil(e, &rc->lasers[i]);
        for (size_t i = 0; r >= 0 && i < e->n_units; i++) {
                struct emu_unit *u = &e->units[i];
                if (!u->is_axis && !(u->map = modbus_mapping_new(u->n_coils, 0, 0, 0)))
                        r = log_error_errno(errno, "relay module: %m");
        }
        return r;
}

DEFINE_TRIVIAL_CLEANUP_FUNC(struct sim_emu *, sim_emu_free);

int sim_emu_new(const struct rig_config *rc, double time_scale, struct sim_emu **ret)
{
        if (!rc || !ret || !(time_scale > 0.0))
                return -EINVAL;

        _cleanup_(sim_emu_freep) struct sim_emu *e = calloc(1, sizeof *e);
        if (!e)
                return -ENOMEM;
        e->rc = rc;
        e->time_scale = time_scale;
        e->epoch_ns = gn_monotonic_ns();
        pthread_mutex_init(&e->lock, NULL);

        int r = add_devices(e);
        for (size_t i = 0; r >= 0 && i < rc->n_buses; i++)
                if (is_modbus(rc->buses[i].type))
                        r = bus_start(e, (int)i);
        if (r >= 0)
                r = sim_gcode_new(rc, time_scale, &e->gcode);
        if (r < 0)
                return r;
        *ret = TAKE_PTR(e);
        return 0;
}

struct sim_emu *sim_emu_free(struct sim_emu *e)
{
        if (!e)
                return NULL;
        atomic_store(&e->stop, true);
        sim_gcode_free(e->gcode);
        for (size_t i = 0; i < e->n_buses; i++)
                bus_stop(&e->buses[i]);
        for (size_t i = 0; i < e->n_units; i++)
                modbus_mapping_free(e->units[i].map);
        pthread_mutex_destroy(&e->lock);
        free(e);
        return NULL;
}

/* ---- queries and faults ---- */

/* Whether switch c is on: false unless it is an emulated "modbus-coil" switch. */
static bool coil_state(struct sim_emu *e, const struct rig_switch_conf *c)
{
        const struct mbsw_conf *mc = c->backend.conf;
        int bi = bus_index(e, c->bus);
        struct emu_unit *u;

        if (strcmp(c->backend.name, "modbus-coil") != 0 || bi < 0)
                return false;
        u = find_unit(e, bi, mc->unit);
        return u && !u->is_axis && mc->coil >= 0 && mc->coil < u->n_coils &&
               u->map->tab_bits[mc->coil];
}

void sim_emu_snapshot(struct sim_emu *e, struct gn_pose *st)
{
        const struct rig_config *rc = e->rc;

        *st = gn_pose_none();
        pthread_mutex_lock(&e->lock);
        double now = emu_now(e);
        for (size_t i = 0; i < e->n_units; i++) {
                struct emu_axis *a = &e->units[i].axis;
                if (!e->units[i].is_axis)
                        continue;
                int role = a->drive.conf->role;
                if (role >= 0 && role < GN_ROLE_COUNT)
                        st->deg[role] = sim_drive_angle(&a->drive, now);
        }
        for (size_t i = 0; i < rc->n_lamps && i < GN_POSE_MAX_LAMPS; i++)
                st->lamps |= (uint32_t)coil_state(e, &rc->lamps[i]) << i;
        for (size_t i = 0; i < rc->n_lasers; i++)
                st->lasers |= (uint32_t)coil_state(e, &rc->lasers[i]) << i;
        pthread_mutex_unlock(&e->lock);
        if (e->gcode)
                sim_gcode_snapshot(e->gcode, st);
}

const char *sim_emu_pty(struct sim_emu *e, const char *bus)
{
        const struct emu_bus *b = find_bus(e, bus);
        if (!b)
                return e->gcode ? sim_gcode_pty(e->gcode, bus) : NULL;
        return b->conf->type == RIG_BUS_MODBUS_RTU ? b->pty.path : NULL;
}

int sim_emu_tcp_port(struct sim_emu *e, const char *bus)
{
        const struct emu_bus *b = find_bus(e, bus);
        return b && b->conf->type == RIG_BUS_MODBUS_TCP ? b->tcp_port : -ENOENT;
}

int sim_emu_unplug(struct sim_emu *e, const char *bus, int ms)
{
        int bi = bus_index(e, bus), none = 0;

        if (e->gcode && sim_gcode_pty(e->gcode, bus))
                return sim_gcode_unplug(e->gcode, bus, ms);
        if (bi < 0 || e->buses[bi].conf->type != RIG_BUS_MODBUS_RTU)
                return -ENOENT;
        if (ms <= 0)
                return -EINVAL;
        return atomic_compare_exchange_strong(&e->buses[bi].unplug_ms, &none, ms) ? 0 : -EBUSY;
}

int sim_emu_inject(struct sim_emu *e, const char *bus, int unit, enum sim_fault fault)
{
        int bi = bus_index(e, bus), r = -ENOENT;

        if (e->gcode && sim_gcode_pty(e->gcode, bus))
                return sim_gcode_inject(e->gcode, bus, fault); /* one controller: no unit */
        if (fault == SIM_FAULT_LATE || fault == SIM_FAULT_ERROR)
                return -EINVAL; /* G-code faults */

        pthread_mutex_lock(&e->lock);
        struct emu_unit *u = bi >= 0 ? find_unit(e, bi, unit) : NULL;
        bool drive_fault = fault == SIM_FAULT_STALL || fault == SIM_FAULT_SHORT;
        if (u && drive_fault) {
                r = u->is_axis ? 0 : -EINVAL;
                if (u->is_axis)
                        sim_drive_inject(&u->axis.drive, emu_now(e),
                                         fault == SIM_FAULT_STALL ? SIM_DRIVE_STALL
                                                                  : SIM_DRIVE_SHORT);
        } else if (u) {
                u->fault = fault;
                if (fault == SIM_FAULT_NONE && u->is_axis)
                        sim_drive_inject(&u->axis.drive, emu_now(e), SIM_DRIVE_OK);
                r = 0;
        }
        pthread_mutex_unlock(&e->lock);
        return r;
}
