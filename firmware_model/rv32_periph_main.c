/* rv32_periph_main.c -- bare-metal harness of the IK peripheral on the soft CPU of ik5r.hdl.soc:
 * every pose solved by the hardware (ik5r_hw_solve, the driver ik5r_hw.c) and by the software
 * solver (ik5r_solve, ik5r.c) in the same firmware, both results written for the host to compare
 * word by word.
 *
 * Job layout (32-bit words), as rv32_main.c except the results:
 *   [0] count N; [1] solves done; [2 + 14 i ...] pose i (p_l[3] a_u[3] n_u[3] o_u[3] flags q5);
 *   [2 + 14 N + 18 i ...] result i: hardware q_a[5] status (blocking call), the same from the
 *   interrupt path (ik5r_hw_start, the handler ik5r_hw_irq_handler reads the result), then the
 *   software's q_a[5] status.
 * All poses go through the hardware first (blocking), then the interrupt path, then the software.
 * MARK: two back to back (the cost of a MARK write), one before the first pose, then per pose one
 * right before and one right after the hardware call: the host times every call from the CPU's
 * side (the call, its 14 stores, the polls and 6 loads, plus one MARK write).
 * STOP: 0 when done; IK5R_RV32_STOP_SELF_CHECK | code when ik5r_self_check fails; 0x1D000000
 * when the peripheral does not answer with its ID.
 */
#include <stdint.h>

#include "ik5r.h"
#include "ik5r_hw.h"

#define IK5R_RV32_MARK (*(volatile uint32_t *)0xF0000000u)
#define IK5R_RV32_STOP_SELF_CHECK 0x5E000000u
#define IK5R_RV32_STOP_NO_PERIPHERAL 0x1D000000u
#define IK5R_RV32_POSE_WORDS 14
#define IK5R_RV32_RESULT_WORDS 18
/* VexRiscv (litex): the machine external interrupt mask CSR of externalInterruptArray. */
#define IK5R_RV32_IRQ_MASK_CSR "0xBC0"
/* A CSR instruction in inline assembly (the build's -march has no Zicsr). */
#define CSR(insn) ".option push\n.option arch, +zicsr\n" insn "\n.option pop"

extern volatile uint32_t ik5r_job[];

typedef struct {
    int32_t p[3], a[3], n[3], o[3], q5;
    int roll, back, down;
} pose_t;

static void load_pose(volatile const uint32_t *words, pose_t *pose)
{
    int i;

    for (i = 0; i < 3; i++) {
        pose->p[i] = (int32_t)words[i];
        pose->a[i] = (int32_t)words[3 + i];
        pose->n[i] = (int32_t)words[6 + i];
        pose->o[i] = (int32_t)words[9 + i];
    }
    pose->roll = (int)(words[12] & 1u);
    pose->back = (int)((words[12] >> 1) & 1u);
    pose->down = (int)((words[12] >> 2) & 1u);
    pose->q5 = (int32_t)words[13];
}

static void store(volatile uint32_t *result, const int32_t q[5], uint32_t status)
{
    int i;

    for (i = 0; i < 5; i++)
        result[i] = (uint32_t)q[i];
    result[5] = status;
}

/* The hardware path on every pose of the job, timed, then the software path: the loop of each
 * stays in the instruction cache (the software solver alone is larger than the cache). */
static void solve_hardware(volatile const uint32_t *poses, volatile uint32_t *results, uint32_t count)
{
    pose_t s;
    int32_t q[5];
    uint32_t i, status;

    for (i = 0; i < count; i++) {
        load_pose(poses + IK5R_RV32_POSE_WORDS * i, &s);
        IK5R_RV32_MARK = 2u * i + 1u;
        status = ik5r_hw_solve(s.p, s.a, s.n, s.o, s.roll, s.back, s.down, s.q5, q);
        IK5R_RV32_MARK = 2u * i + 2u;
        store(results + IK5R_RV32_RESULT_WORDS * i, q, status);
    }
}

void ik5r_rv32_irq(void);
void ik5r_rv32_irq(void)
{
    ik5r_hw_irq_handler();
}

static void irq_on(void)
{
    ik5r_hw_irq_enable(1);
    __asm__ volatile(CSR("csrw " IK5R_RV32_IRQ_MASK_CSR ", %0") : : "r"(1u));
    __asm__ volatile(CSR("csrs mie, %0") : : "r"(1u << 11));   /* MEIE */
    __asm__ volatile(CSR("csrs mstatus, %0") : : "r"(1u << 3)); /* MIE */
}

/* Start each pose, wait for the interrupt handler to have taken its result. */
static void solve_by_interrupt(volatile const uint32_t *poses, volatile uint32_t *results, uint32_t count)
{
    pose_t s;
    int32_t q[5];
    uint32_t i, j, seen;

    irq_on();
    for (i = 0; i < count; i++) {
        load_pose(poses + IK5R_RV32_POSE_WORDS * i, &s);
        seen = ik5r_hw_irq_count;
        (void)ik5r_hw_start(s.p, s.a, s.n, s.o, s.roll, s.back, s.down, s.q5);
        while (ik5r_hw_irq_count == seen)
            ;
        for (j = 0; j < 5; j++)
            q[j] = ik5r_hw_last.q_a[j];
        store(results + IK5R_RV32_RESULT_WORDS * i + 6, q, ik5r_hw_last.status);
    }
    __asm__ volatile(CSR("csrc mstatus, %0") : : "r"(1u << 3));
    ik5r_hw_irq_enable(0);
}

static void solve_software(volatile const uint32_t *poses, volatile uint32_t *results, uint32_t count)
{
    pose_t s;
    int32_t q[5];
    uint32_t i, status;

    for (i = 0; i < count; i++) {
        load_pose(poses + IK5R_RV32_POSE_WORDS * i, &s);
        status = ik5r_solve(s.p, s.a, s.n, s.o, s.roll, s.back, s.down, s.q5, q);
        store(results + IK5R_RV32_RESULT_WORDS * i + 12, q, status);
        ik5r_job[1] = i + 1;
    }
}

int main(void)
{
    uint32_t count = ik5r_job[0];
    volatile uint32_t *poses = ik5r_job + 2;
    volatile uint32_t *results = poses + IK5R_RV32_POSE_WORDS * count;
    int check = ik5r_self_check();

    if (check != 0)
        return (int)(IK5R_RV32_STOP_SELF_CHECK | (uint32_t)check);
    if (ik5r_hw_probe() != 0)
        return (int)IK5R_RV32_STOP_NO_PERIPHERAL;
    ik5r_job[1] = 0;
    IK5R_RV32_MARK = 0xFFFFFFFFu;
    IK5R_RV32_MARK = 0xFFFFFFFFu;
    IK5R_RV32_MARK = 0;
    solve_hardware(poses, results, count);
    solve_by_interrupt(poses, results, count);
    solve_software(poses, results, count);
    return 0;
}
