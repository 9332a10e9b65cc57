/* rv32_main.c -- bare-metal harness of ik5r.c on the soft CPU of ik5r.hdl.soc.
 *
 * The host (a simulation of the SoC) writes a job into RAM at ik5r_job (linker script rv32.ld)
 * while the CPU is held in reset, releases it, and reads the results back after the STOP write.
 * Job layout, 32-bit words:
 *   [0] count N; [1] solves done (written here, for the host to check an early stop);
 *   [2 + 14 i ...] pose i: p_l[3] a_u[3] n_u[3] o_u[3] flags q5_default_a
 *                  (flags: bit 0 has_roll, bit 1 shoulder_back, bit 2 elbow_down);
 *   [2 + 14 N + 6 i ...] result i: q_a[5] status.
 * MARK is written once before the first solve and once after each, so that the host can time
 * every solve (pose read, ik5r_solve, result write: the loop of a real firmware); two MARK writes
 * back to back before that measure the cost of a MARK write itself.
 * STOP: 0 after the last solve; IK5R_RV32_STOP_SELF_CHECK | code when ik5r_self_check fails;
 * the trap handler in rv32_start.S writes IK5R_RV32_STOP_TRAP | mcause.
 */
#include <stdint.h>

#include "ik5r.h"

#define IK5R_RV32_MARK (*(volatile uint32_t *)0xF0000000u)
#define IK5R_RV32_STOP (*(volatile uint32_t *)0xF0000004u)
#define IK5R_RV32_STOP_SELF_CHECK 0x5E000000u
#define IK5R_RV32_POSE_WORDS 14
#define IK5R_RV32_RESULT_WORDS 6

extern volatile uint32_t ik5r_job[];

static uint32_t solve_one(volatile const uint32_t *pose, volatile uint32_t *result)
{
    int32_t p[3], a[3], n[3], o[3], q[5];
    uint32_t flags, status;
    int i;

    for (i = 0; i < 3; i++) {
        p[i] = (int32_t)pose[i];
        a[i] = (int32_t)pose[3 + i];
        n[i] = (int32_t)pose[6 + i];
        o[i] = (int32_t)pose[9 + i];
    }
    flags = pose[12];
    status = ik5r_solve(p, a, n, o, (int)(flags & 1u), (int)((flags >> 1) & 1u),
                        (int)((flags >> 2) & 1u), (int32_t)pose[13], q);
    for (i = 0; i < 5; i++)
        result[i] = (uint32_t)q[i];
    result[5] = status;
    return status;
}

int main(void)
{
    uint32_t count = ik5r_job[0], i;
    volatile uint32_t *poses = ik5r_job + 2;
    volatile uint32_t *results = poses + IK5R_RV32_POSE_WORDS * count;
    int check = ik5r_self_check();

    if (check != 0)
        return (int)(IK5R_RV32_STOP_SELF_CHECK | (uint32_t)check);
    ik5r_job[1] = 0;
    IK5R_RV32_MARK = 0xFFFFFFFFu;
    IK5R_RV32_MARK = 0xFFFFFFFFu;
    IK5R_RV32_MARK = 0;
    for (i = 0; i < count; i++) {
        (void)solve_one(poses + IK5R_RV32_POSE_WORDS * i, results + IK5R_RV32_RESULT_WORDS * i);
        ik5r_job[1] = i + 1;
        IK5R_RV32_MARK = i + 1;
    }
    return 0;
}
