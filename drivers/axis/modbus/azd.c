/* azd.c - the built-in "azd" register profile: Oriental Motor's AZ series drivers (AZD-*D,
 * AZD-*X, the AZ motors with a built-in driver) in their Modbus RTU mode, pure encoding and
 * decoding. A move is one "direct data operation": the 16-register block at 0x0058 written
 * at once with its trigger 1, which makes the drive take the data and start. Home, stop
 * and alarm reset are edges of the driver input command (ZHOME, STOP, ALM-RST): the bit
 * on, then all off. The state is the driver output status (MOVE, IN-POS, HOME-END, ALM-A),
 * the present alarm code and the feedback position. Sources: docs/modbus-profile.md. */
#include <errno.h>
#include <math.h>

#include "common/cleanup.h"
#include "drivers/axis/modbus/proto.h"

/* Ranges of the direct data operation (Hz and kHz/s in 0.001 units). */
#define AZD_SPEED_MAX 4000000.0
#define AZD_RATE_MAX  1000000000.0

void mbax_azd_decode_status(uint16_t output, int32_t alarm, struct axis_state *st)
{
        st->fault = output & AZD_OUT_ALM_A;
        st->enabled = !st->fault;
        st->homed = output & AZD_OUT_HOME_END;
        st->moving = output & AZD_OUT_MOVE;
        st->in_position = (output & AZD_OUT_IN_POS) && !st->moving && !st->fault;
        st->fault_code = st->fault ? alarm : 0;
}

static int azd_spans(const struct mbax_conf *c, struct mbax_span s[MBAX_SPANS_MAX])
{
        (void)c;
        s[0] = (struct mbax_span){"read driver output status and alarm", AZD_REG_OUTPUT, 4};
        s[1] = (struct mbax_span){"read feedback position", AZD_REG_FEEDBACK_POS, 2};
        return 2;
}

static void azd_decode(const struct mbax_conf *c, const uint16_t *regs, struct axis_state *st,
                       int32_t *counts)
{
        mbax_azd_decode_status(regs[1], mbax_get_i32(c->word_swap, regs + 2), st);
        *counts = mbax_get_i32(c->word_swap, regs + 4);
}

static int azd_rates(const struct mbax_conf *c, double speed, double accel,
                     struct mbax_write w[MBAX_WRITES_MAX])
{
        (void)c, (void)speed, (void)accel, (void)w; /* every move carries them */
        return 0;
}

/* v (steps/s or steps/s^2) as an int32 field of at least 1; -ERANGE above max. */
static int put_rate(const struct mbax_conf *c, double v, double max, uint16_t regs[2])
{
        double r = round(v);

        if (!(r <= max))
                return -ERANGE;
        mbax_put_i32(c->word_swap, (int32_t)MAX(r, 1.0), regs);
        return 0;
}

static int azd_move(const struct mbax_conf *c, int32_t target, double speed, double accel,
                    struct mbax_write w[MBAX_WRITES_MAX])
{
        uint16_t *d = w[0].regs;
        int r;

        w[0] = (struct mbax_write){.what = "write direct data operation",
                                   .addr = AZD_REG_DIRECT,
                                   .n = AZD_DIRECT_REGS};
        mbax_put_i32(c->word_swap, 0, d);                   /* operation data No. 0 */
        mbax_put_i32(c->word_swap, AZD_OP_ABSOLUTE, d + 2); /* type */
        mbax_put_i32(c->word_swap, target, d + 4);          /* position, steps */
        if ((r = put_rate(c, speed * c->scale, AZD_SPEED_MAX, d + 6)) < 0 || /* Hz */
            (r = put_rate(c, accel * c->scale, AZD_RATE_MAX, d + 8)) < 0 ||  /* starting */
            (r = put_rate(c, accel * c->scale, AZD_RATE_MAX, d + 10)) < 0)   /* stopping */
                return r;
        mbax_put_i32(c->word_swap, AZD_CURRENT_FULL, d + 12);
        mbax_put_i32(c->word_swap, 1, d + 14); /* trigger: reflect all, start */
        return 1;
}

static int azd_command(const struct mbax_conf *c, enum mbax_cmd cmd,
                       struct mbax_write w[MBAX_WRITES_MAX])
{
        uint16_t bit = cmd == MBAX_CMD_HOME   ? AZD_IN_ZHOME
                       : cmd == MBAX_CMD_STOP ? AZD_IN_STOP
                                              : AZD_IN_ALM_RST;

        w[0] = (struct mbax_write){
                .what = "write driver input command", .addr = AZD_REG_INPUT, .n = 2};
        mbax_put_i32(c->word_swap, bit, w[0].regs);
        w[1] = w[0]; /* the edge ends: all inputs off */
        mbax_put_i32(c->word_swap, 0, w[1].regs);
        return 2;
}

const struct mbax_family mbax_azd = {
        .name = "azd",
        .spans = azd_spans,
        .decode = azd_decode,
        .rates = azd_rates,
        .move = azd_move,
        .command = azd_command,
};
