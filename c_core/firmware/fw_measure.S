/*
 * Cost measurement on the Cortex-M4F under QEMU (c_core/firmware/README.md, "Counting
 * instructions"). Every routine here is a leaf that touches no stack, so a painted-stack
 * measurement around a call sees only the call.
 *
 * Instruction counting. QEMU run with -icount shift=0 advances virtual time by exactly 1 ns
 * per executed instruction; SysTick on the processor clock (25 MHz on mps2-an386) then
 * decrements once every 40 instructions. A plain read of SysTick therefore has a 40
 * instruction granularity. rio_sync removes it with a vernier: it samples SysTick once per
 * loop iteration of exactly 41 instructions, so each sample lands one instruction later
 * in the 40-instruction tick than the one before; two consecutive samples differ by 2
 * ticks exactly when the second one was taken on the first instruction of a tick. It
 * returns at that moment, with the sample and the number of iterations. Two such stamps
 * around a call are a whole number of ticks apart, and
 *     instructions = 40 * ticks - 41 * (iterations of the second stamp) - constant,
 * the constant being calibrated once on an empty call (replay_main.c).
 */
    .syntax unified
    .cpu cortex-m4
    .thumb

    .equ SYST_CVR, 0xE000E018
    .equ STACK_PATTERN, 0xDEADBEEF
    .equ VERNIER_NOPS, 33           /* 8 + 33 = 41 instructions per iteration */

/* uint64_t rio_sync(void): low word = SysTick value sampled on a tick's first
 * instruction, high word = loop iterations it took (>= 2). */
    .section .text.rio_sync,"ax",%progbits
    .global rio_sync
    .type rio_sync, %function
    .thumb_func
rio_sync:
    ldr r3, =SYST_CVR
    ldr r2, [r3]                    /* previous sample */
    movs r1, #0                     /* iterations */
1:  ldr r0, [r3]                    /*  1 sample */
    subs r12, r2, r0                /*  2 previous - current: SysTick counts down */
    bic r12, r12, #0xFF000000       /*  3 the counter is 24 bits */
    mov r2, r0                      /*  4 */
    adds r1, r1, #1                 /*  5 */
    cmp r12, #2                     /*  6 */
    beq 2f                          /*  7 */
    .rept VERNIER_NOPS
    nop                             /*  8 .. 40 */
    .endr
    b 1b                            /* 41 */
2:  bx lr
    .ltorg
    .size rio_sync, . - rio_sync

/* void rio_spin(uint32_t n): exactly 2n + 1 instructions, n >= 1. */
    .section .text.rio_spin,"ax",%progbits
    .global rio_spin
    .type rio_spin, %function
    .thumb_func
rio_spin:
1:  subs r0, r0, #1
    bne 1b
    bx lr
    .size rio_spin, . - rio_spin

/* void rio_nop(void): one instruction. */
    .section .text.rio_nop,"ax",%progbits
    .global rio_nop
    .type rio_nop, %function
    .thumb_func
rio_nop:
    bx lr
    .size rio_nop, . - rio_nop

/* void rio_stack_paint(void): fill [__stack_limit, sp) with STACK_PATTERN and remember sp. */
    .section .text.rio_stack_paint,"ax",%progbits
    .global rio_stack_paint
    .type rio_stack_paint, %function
    .thumb_func
rio_stack_paint:
    ldr r0, =__stack_limit
    mov r1, sp
    ldr r3, =fw_painted_sp
    str r1, [r3]
    ldr r2, =STACK_PATTERN
1:  cmp r0, r1                      /* sp and the limit are 8-byte aligned */
    bhs 2f
    strd r2, r2, [r0], #8
    b 1b
2:  bx lr
    .ltorg
    .size rio_stack_paint, . - rio_stack_paint

/* uint32_t rio_stack_used(void): bytes below the painted sp that no longer hold the pattern. */
    .section .text.rio_stack_used,"ax",%progbits
    .global rio_stack_used
    .type rio_stack_used, %function
    .thumb_func
rio_stack_used:
    ldr r0, =__stack_limit
    ldr r3, =fw_painted_sp
    ldr r1, [r3]
    ldr r2, =STACK_PATTERN
1:  cmp r0, r1
    bhs 2f
    ldr r3, [r0]
    cmp r3, r2
    bne 2f
    adds r0, r0, #4
    b 1b
2:  subs r0, r1, r0
    bx lr
    .ltorg
    .size rio_stack_used, . - rio_stack_used

    .section .bss.fw_painted_sp,"aw",%nobits
    .align 2
fw_painted_sp:
    .space 4
