/* test-mbax-proto.c - the pure encode/decode of the Modbus axis register profile and of
 * the coil switch: word order, counts <-> degrees, count targets of a travel, status bits. */
#include <errno.h>
#include <stdint.h>

#include "drivers/axis/modbus/proto.h"
#include "drivers/switch/modbus/proto.h"
#include "tests/test.h"

static struct rig_modbus_profile profile(bool word_swap, double scale)
{
        struct rig_modbus_profile p = {.scale = scale, .word_swap = word_swap};

        return p;
}

static void test_word_order(void)
{
        struct rig_modbus_profile hi = profile(false, 1000), lo = profile(true, 1000);
        uint16_t regs[2];

        mbax_put_i32(&hi, 0x12345678, regs);
        CHECK_INT(regs[0], 0x1234);
        CHECK_INT(regs[1], 0x5678);
        CHECK_INT(mbax_get_i32(&hi, regs), 0x12345678);
        mbax_put_i32(&lo, 0x12345678, regs);
        CHECK_INT(regs[0], 0x5678);
        CHECK_INT(regs[1], 0x1234);
        CHECK_INT(mbax_get_i32(&lo, regs), 0x12345678);

        mbax_put_i32(&hi, -2, regs); /* two's complement across both words */
        CHECK_INT(regs[0], 0xffff);
        CHECK_INT(regs[1], 0xfffe);
        CHECK_INT(mbax_get_i32(&hi, regs), -2);
        mbax_put_i32(&hi, INT32_MIN, regs);
        CHECK_INT(mbax_get_i32(&hi, regs), INT32_MIN);
}

static void test_counts(void)
{
        struct rig_modbus_profile p = profile(false, 1000), bad = profile(false, 0);
        int32_t c;

        CHECK_INT(mbax_deg_to_counts(&p, 12.3456, &c), 0);
        CHECK_INT(c, 12346);
        CHECK_INT(mbax_deg_to_counts(&p, -170.0004, &c), 0);
        CHECK_INT(c, -170000);
        CHECK_INT(mbax_deg_to_counts(&p, 3e6, &c), -ERANGE); /* 3e9 counts > INT32_MAX */
        CHECK_INT(mbax_deg_to_counts(&p, NAN, &c), -ERANGE);
        CHECK_INT(mbax_deg_to_counts(&bad, 1.0, &c), -ERANGE);

        CHECK_NEAR(mbax_counts_to_deg(&p, -170000, false), -170.0, 1e-12);
        CHECK_NEAR(mbax_counts_to_deg(&p, 370000, false), 370.0, 1e-12);
        CHECK_NEAR(mbax_counts_to_deg(&p, 370000, true), 10.0, 1e-9);
        CHECK_NEAR(mbax_counts_to_deg(&p, -90000, true), 270.0, 1e-9);
        CHECK_NEAR(mbax_counts_to_deg(&p, -720000, true), 0.0, 1e-12);
        CHECK(mbax_counts_to_deg(&p, -1, true) < 360.0);
        CHECK_NEAR(mbax_counts_to_deg(&p, -1, true), 359.999, 1e-9);
}

/* The count target of a travel the axis class chose (axis_travel, test-classes). */
static void test_count_target(void)
{
        struct rig_modbus_profile p = profile(false, 1000);
        int32_t t;

        CHECK_INT(mbax_count_target(&p, 350000, 20.0, &t), 0);
        CHECK_INT(t, 370000); /* forward across 360: the counter keeps going */
        CHECK_INT(mbax_count_target(&p, 10000, -20.0, &t), 0);
        CHECK_INT(t, -10000);
        CHECK_INT(mbax_count_target(&p, INT32_MAX - 10, 180.0, &t), -ERANGE);
        CHECK_INT(mbax_count_target(&p, 0, INFINITY, &t), -ERANGE);
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
        test_coil();
        return 0;
}
