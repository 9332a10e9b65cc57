/* rv32_start.S -- reset entry of the rv32 harness: stack, global pointer, trap vector, .bss,
 * main(); then main's return value to the STOP register (and spin). A trap (illegal
 * instruction, misaligned access, ...) writes 0xBAD00000 | mcause to STOP. */
    .option arch, +zicsr
    .section .text.start, "ax"
    .globl _start
_start:
    .option push
    .option norelax
    la gp, __global_pointer$
    .option pop
    la sp, __stack_top
    la t0, ik5r_trap
    csrw mtvec, t0
    la t0, __bss_start
    la t1, __bss_end
1:  bgeu t0, t1, 2f
    sw zero, 0(t0)
    addi t0, t0, 4
    j 1b
2:  call main
    li t0, 0xF0000004
    sw a0, 0(t0)
3:  j 3b

    .balign 4
ik5r_trap:
    csrr t1, mcause
    li t2, 0xBAD00000
    or t1, t1, t2
    li t0, 0xF0000004
    sw t1, 0(t0)
4:  j 4b
