/* ik5r_hw.h -- driver of the ik5r IK peripheral (Wishbone slave, register map ik5r_regs.h).
 *
 * ik5r_hw_solve() has the call of the software solver ik5r_solve() (ik5r.h): the same words in,
 * the same joint words and status bits out, bit for bit. Three ways to use the core:
 *   - blocking: ik5r_hw_solve() (write the pose, start, poll RESULT.VALID, read the joints);
 *   - start/poll: ik5r_hw_start(), then ik5r_hw_done() until non-zero, then ik5r_hw_result();
 *     up to the core's CAPACITY poses may be started before the first result is read (the
 *     results come back in start order, each with its tag);
 *   - interrupt: ik5r_hw_irq_enable(1); the interrupt line is high while a result waits; the
 *     handler calls ik5r_hw_result() (which pops it and so lowers the line) or
 *     ik5r_hw_irq_handler() (stores it in ik5r_hw_last and counts it in ik5r_hw_irq_count).
 *
 * Build switch: with IK5R_SOLVER_HW defined, ik5r_solve() in every file that includes this
 * header after ik5r.h is the hardware call (a macro), so firmware picks its path by one -D.
 * IK5R_HW_BASE (ik5r_regs.h) is the base address: the ik5r SoC's by default, a LiteX build
 * defines it from its csr.h.
 */
#ifndef IK5R_HW_H
#define IK5R_HW_H

#include <stdint.h>

#include "ik5r_regs.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A result read back from the core. */
typedef struct {
    int32_t q_a[5];
    uint32_t status;  /* IK5R_STATUS_* bits */
    uint32_t tag;     /* the count of starts before this pose's, mod 2^IK5R_HW_TAG_BITS */
} ik5r_hw_result_t;

/* 0 when the peripheral answers with the ID magic at IK5R_HW_BASE, else -1. */
int ik5r_hw_probe(void);

/* Write the pose and start it; returns 0, or -1 when the start was dropped (queue full:
 * EVENTS.OVERRUN, cleared here). */
int ik5r_hw_start(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                  const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                  int32_t q5_default_a);

/* Non-zero when a result waits (RESULT.VALID). */
int ik5r_hw_done(void);

/* Read the waiting result and pop it; returns 0, or -1 when none waited (nothing read). */
int ik5r_hw_result(ik5r_hw_result_t *out);

/* ik5r_solve() on the core: blocking, the software solver's arguments and results. */
uint32_t ik5r_hw_solve(const int32_t p_l[3], const int32_t a_u[3], const int32_t n_u[3],
                       const int32_t o_u[3], int has_roll, int shoulder_back, int elbow_down,
                       int32_t q5_default_a, int32_t q_a[5]);

/* Interrupt path. */
void ik5r_hw_irq_enable(int on);
void ik5r_hw_irq_handler(void);
extern volatile ik5r_hw_result_t ik5r_hw_last;
extern volatile uint32_t ik5r_hw_irq_count;

#ifdef IK5R_SOLVER_HW
#define ik5r_solve ik5r_hw_solve
#endif

#ifdef __cplusplus
}
#endif

#endif /* IK5R_HW_H */
