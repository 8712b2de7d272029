/* test-mbax-proto.c - the pure encode/decode of the Modbus axis register profile and of
 * the coil switch: word order, counts <-> degrees, count targets of a travel, status bits,
 * and the "azd" family's writes and decoding. */
#include <errno.h>
#include <stdint.h>

#include "drivers/axis/modbus/proto.h"
#include "drivers/switch/modbus/proto.h"
#include "tests/test.h"

static void test_word_order(void)
{
        const bool hi = false, lo = true;
        uint16_t regs[2];

        mbax_put_i32(hi, 0x12345678, regs);
        CHECK_INT(regs[0], 0x1234);
        CHECK_INT(regs[1], 0x5678);
        CHECK_INT(mbax_get_i32(hi, regs), 0x12345678);
        mbax_put_i32(lo, 0x12345678, regs);
        CHECK_INT(regs[0], 0x5678);
        CHECK_INT(regs[1], 0x1234);
        CHECK_INT(mbax_get_i32(lo, regs), 0x12345678);

        mbax_put_i32(hi, -2, regs); /* two's complement across both words */
        CHECK_INT(regs[0], 0xffff);
        CHECK_INT(regs[1], 0xfffe);
        CHECK_INT(mbax_get_i32(hi, regs), -2);
        mbax_put_i32(hi, INT32_MIN, regs);
        CHECK_INT(mbax_get_i32(hi, regs), INT32_MIN);
}

static void test_counts(void)
{
        const double p = 1000, bad = 0;
        int32_t c;

        CHECK_INT(mbax_deg_to_counts(p, 12.3456, &c), 0);
        CHECK_INT(c, 12346);
        CHECK_INT(mbax_deg_to_counts(p, -170.0004, &c), 0);
        CHECK_INT(c, -170000);
        CHECK_INT(mbax_deg_to_counts(p, 3e6, &c), -ERANGE); /* 3e9 counts > INT32_MAX */
        CHECK_INT(mbax_deg_to_counts(p, NAN, &c), -ERANGE);
        CHECK_INT(mbax_deg_to_counts(bad, 1.0, &c), -ERANGE);

        CHECK_NEAR(mbax_counts_to_deg(p, -170000, false), -170.0, 1e-12);
        CHECK_NEAR(mbax_counts_to_deg(p, 370000, false), 370.0, 1e-12);
        CHECK_NEAR(mbax_counts_to_deg(p, 370000, true), 10.0, 1e-9);
        CHECK_NEAR(mbax_counts_to_deg(p, -90000, true), 270.0, 1e-9);
        CHECK_NEAR(mbax_counts_to_deg(p, -720000, true), 0.0, 1e-12);
        CHECK(mbax_counts_to_deg(p, -1, true) < 360.0);
        CHECK_NEAR(mbax_counts_to_deg(p, -1, true), 359.999, 1e-9);
}

/* The count target of a travel the axis class chose (axis_travel, test-classes). */
static void test_count_target(void)
{
        const double p = 1000;
        int32_t t;

        CHECK_INT(mbax_count_target(p, 350000, 20.0, &t), 0);
        CHECK_INT(t, 370000); /* forward across 360: the counter keeps going */
        CHECK_INT(mbax_count_target(p, 10000, -20.0, &t), 0);
        CHECK_INT(t, -10000);
        CHECK_INT(mbax_count_target(p, INT32_MAX - 10, 180.0, &t), -ERANGE);
        CHECK_INT(mbax_count_target(p, 0, INFINITY, &t), -ERANGE);
}

static void test_status(void)
{
        struct axis_state st = {};

        mbax_decode_status(AXIS_ST_ENABLED | AXIS_ST_HOMED | AXIS_ST_IN_POSITION, 0, &st);
        CHECK(st.enabled && st.homed && st.in_position);
        CHECK(!st.moving && !st.fault);
        CHECK_INT(st.fault_code, 0);
        mbax_decode_status(AXIS_ST_ENABLED | AXIS_ST_FAULT, MBAX_FAULT_STALL, &st);
        CHECK(st.fault && !st.homed && !st.in_position);
        CHECK_INT(st.fault_code, 1);
        mbax_decode_status(AXIS_ST_MOVING, 3, &st); /* stale code without the bit: no fault */
        CHECK(st.moving && !st.fault);
        CHECK_INT(st.fault_code, 0);
}

static void test_rates(void)
{
        CHECK_INT(mbax_rate_reg(90.0), 900);
        CHECK_INT(mbax_rate_reg(0.04), 1);
        CHECK_INT(mbax_rate_reg(-5), 1);
        CHECK_INT(mbax_rate_reg(NAN), 1);
        CHECK_INT(mbax_rate_reg(1e6), 65535);
}

/* The AZ's driver output status and alarm code (bits as docs/modbus-profile.md gives them,
 * not from the header): ALM-A (7) is the fault with the alarm code, IN-POS (14) counts only
 * at rest, MOVE is 13, HOME-END (4) is homed, READY 5. */
static void test_azd_status(void)
{
        struct axis_state st = {};

        mbax_azd_decode_status(0x0020 | 0x0010 | 0x4000, 0, &st);
        CHECK(st.enabled && st.homed && st.in_position);
        CHECK(!st.moving && !st.fault);
        mbax_azd_decode_status(0x2000 | 0x4000, 0, &st); /* passing through */
        CHECK(st.moving && !st.in_position && !st.homed);
        mbax_azd_decode_status(0x0080, 0x10, &st);
        CHECK(st.fault && !st.enabled && !st.in_position);
        CHECK_INT(st.fault_code, 0x10);
        mbax_azd_decode_status(0x0020, 0x10, &st); /* a code without ALM-A: no fault */
        CHECK(!st.fault);
        CHECK_INT(st.fault_code, 0);
}

/* A move is one 16-register direct data operation at 0x0058, upper words first: data No. 0,
 * absolute positioning, the position, speed in Hz and rates in steps/s^2 at the axis's
 * scale, 100 % current, trigger 1; home/stop/reset are an input bit then all off. */
static void test_azd_encode(void)
{
        static const uint16_t expect[16] = {0, 0,     0, 1,     0xffff, 0xfc18, 0, 2000,
                                            0, 18000, 0, 18000, 0,      1000,   0, 1};
        struct mbax_conf c = {.unit = 3, .family = &mbax_azd, .scale = 100};
        struct mbax_write w[MBAX_WRITES_MAX];
        struct mbax_span s[MBAX_SPANS_MAX];
        uint16_t regs[] = {0, 0x2000, 0, 0, 0x0001, 0x86a0}; /* MOVE */
        struct axis_state st;
        int32_t counts;

        CHECK_INT(mbax_azd.move(&c, -1000, 20.0, 180.0, w), 1);
        CHECK_INT(w[0].addr, 0x0058);
        CHECK_INT(w[0].n, 16);
        for (int i = 0; i < 16; i++)
                CHECK_INT(w[0].regs[i], expect[i]);
        CHECK_INT(mbax_azd.move(&c, 0, 1e5, 180.0, w), -ERANGE); /* 10 MHz */
        CHECK_INT(mbax_azd.rates(&c, 20.0, 180.0, w), 0);

        CHECK_INT(mbax_azd.command(&c, MBAX_CMD_STOP, w), 2);
        CHECK_INT(w[0].addr, 0x007c);
        CHECK_INT(w[0].regs[0], 0);
        CHECK_INT(w[0].regs[1], 0x20);
        CHECK_INT(w[1].regs[1], 0);
        CHECK_INT(mbax_azd.command(&c, MBAX_CMD_HOME, w), 2);
        CHECK_INT(w[0].regs[1], 0x10);
        CHECK_INT(mbax_azd.command(&c, MBAX_CMD_RESET, w), 2);
        CHECK_INT(w[0].regs[1], 0x80);

        CHECK_INT(mbax_azd.spans(&c, s), 2);
        CHECK_INT(s[0].addr, 0x007e);
        CHECK_INT(s[1].addr, 0x00cc);
        mbax_azd.decode(&c, regs, &st, &counts);
        CHECK(st.moving);
        CHECK_INT(counts, 100000);
}

static void test_coil(void)
{
        struct mbsw_conf c = {.unit = 10, .coil = 7};
        bool on = false;

        CHECK_INT(mbsw_check_conf(&c), 0);
        CHECK_INT(mbsw_check_conf(NULL), -EINVAL); /* a conf built without the rig file */
        c.unit = 248;
        CHECK_INT(mbsw_check_conf(&c), -EINVAL);
        c.unit = 1;
        c.coil = 70000;
        CHECK_INT(mbsw_check_conf(&c), -EINVAL);
        CHECK_INT(mbsw_decode_coil(1, &on), 0);
        CHECK(on);
        CHECK_INT(mbsw_decode_coil(0, &on), 0);
        CHECK(!on);
        CHECK_INT(mbsw_decode_coil(0xff, &on), -EPROTO);
}

int main(void)
{
        test_word_order();
        test_counts();
        test_count_target();
        test_status();
        test_rates();
        test_azd_status();
        test_azd_encode();
        test_coil();
        return 0;
}
