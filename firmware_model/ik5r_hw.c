/* ik5r_hw.c -- driver of the ik5r IK peripheral: see ik5r_hw.h. */
#include "ik5r_hw.h"

#define REG(name) IK5R_HW_REG(IK5R_REG_##name)

volatile ik5r_hw_result_t ik5r_hw_last;
volatile uint32_t ik5r_hw_irq_count;

int ik5r_hw_probe(void)
{
    return REG(ID) == 0x494B3552u ? 0 : -1;
}

/* The pose words in register order (PX .. Q5_DEFAULT are consecutive), then CTRL: fourteen
 * stores, the last one starts the core. Every word is read from RAM before the first store: on
 * VexRiscv a cached load behind an uncached store waits for the store, so interleaving them
 * costs about five clocks a word. */
static void write_pose(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                       const int32_t o_u[3], int has_roll, int32_t q5_default_a, uint32_t ctrl)
{
    volatile uint32_t *reg = &REG(PX);
    const int32_t zeros[3] = {0, 0, 0};
    int roll = has_roll && n_u != 0 && o_u != 0;
    const int32_t *n = roll ? n_u : zeros, *o = roll ? o_u : zeros;
    uint32_t px = (uint32_t)p_l[0], py = (uint32_t)p_l[1], pz = (uint32_t)p_l[2];
    uint32_t ax = (uint32_t)a_u[0], ay = (uint32_t)a_u[1], az = (uint32_t)a_u[2];
    uint32_t nx = (uint32_t)n[0], ny = (uint32_t)n[1], nz = (uint32_t)n[2];
    uint32_t ox = (uint32_t)o[0], oy = (uint32_t)o[1], oz = (uint32_t)o[2];

    ctrl |= roll ? IK5R_CTRL_HAS_ROLL_MASK : 0u;
    reg[0] = px;
    reg[1] = py;
    reg[2] = pz;
    reg[3] = ax;
    reg[4] = ay;
    reg[5] = az;
    reg[6] = nx;
    reg[7] = ny;
    reg[8] = nz;
    reg[9] = ox;
    reg[10] = oy;
    reg[11] = oz;
    reg[12] = (uint32_t)q5_default_a;
    reg[13] = ctrl;
}

static uint32_t ctrl_word(int shoulder_back, int elbow_down)
{
    return IK5R_CTRL_START_MASK | (shoulder_back ? IK5R_CTRL_SHOULDER_BACK_MASK : 0u)
           | (elbow_down ? IK5R_CTRL_ELBOW_DOWN_MASK : 0u);
}

int ik5r_hw_start(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                  const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                  int32_t q5_default_a)
{
    write_pose(p_l, a_u, n_u, o_u, has_roll, q5_default_a, ctrl_word(shoulder_back, elbow_down));
    if (REG(EVENTS) & IK5R_EVENTS_OVERRUN_MASK) {
        REG(EVENTS) = IK5R_EVENTS_OVERRUN_MASK;
        return -1;
    }
    return 0;
}

int ik5r_hw_done(void)
{
    return (REG(RESULT) & IK5R_RESULT_VALID_MASK) != 0;
}

/* Q1..Q5 after RESULT: the read of Q5 pops the result. All five are loaded before the first
 * store to q_a (a cached store between uncached loads makes the next load wait). */
static uint32_t read_joints(uint32_t result, int32_t q_a[5])
{
    volatile uint32_t *q = &REG(Q1);
    uint32_t q1 = q[0], q2 = q[1], q3 = q[2], q4 = q[3], q5 = q[4];

    q_a[0] = (int32_t)q1;
    q_a[1] = (int32_t)q2;
    q_a[2] = (int32_t)q3;
    q_a[3] = (int32_t)q4;
    q_a[4] = (int32_t)q5;
    return (result & IK5R_RESULT_STATUS_MASK) >> IK5R_RESULT_STATUS_SHIFT;
}

int ik5r_hw_result(ik5r_hw_result_t *out)
{
    uint32_t result = REG(RESULT);

    if (!(result & IK5R_RESULT_VALID_MASK))
        return -1;
    out->tag = (result & IK5R_RESULT_TAG_MASK) >> IK5R_RESULT_TAG_SHIFT;
    out->status = read_joints(result, out->q_a);
    return 0;
}

uint32_t ik5r_hw_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                       const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                       int32_t q5_default_a, int32_t q_a[5])
{
    uint32_t result;

    write_pose(p_l, a_u, n_u, o_u, has_roll, q5_default_a, ctrl_word(shoulder_back, elbow_down));
    do {
        result = REG(RESULT);
    } while (!(result & IK5R_RESULT_VALID_MASK));
    return read_joints(result, q_a);
}

void ik5r_hw_irq_enable(int on)
{
    REG(IRQ_ENABLE) = on ? IK5R_IRQ_ENABLE_DONE_MASK : 0u;
}

void ik5r_hw_irq_handler(void)
{
    ik5r_hw_result_t r;

    if (ik5r_hw_result(&r) == 0) {
        int i;
        for (i = 0; i < 5; i++)
            ik5r_hw_last.q_a[i] = r.q_a[i];
        ik5r_hw_last.status = r.status;
        ik5r_hw_last.tag = r.tag;
        ik5r_hw_irq_count++;
    }
}
