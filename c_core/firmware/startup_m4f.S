/*
 * Cortex-M4F startup for QEMU mps2-an386 (and any M4F with code at 0, RAM elsewhere):
 * vector table, Reset_Handler, fault handlers. Written in assembly so that nothing runs a
 * floating-point instruction before the FPU is enabled.
 *
 * Reset_Handler: enable CP10/CP11 (FPU) in CPACR, copy .data from flash, zero .bss, paint
 * the stack (for the high-water mark), call main(0, NULL), exit through semihosting with
 * main's return value.
 */
    .syntax unified
    .cpu cortex-m4
    .fpu fpv4-sp-d16
    .thumb

    .equ CPACR, 0xE000ED88
    .equ STACK_PATTERN, 0xDEADBEEF

    .section .isr_vector,"a",%progbits
    .align 2
    .global __isr_vector
__isr_vector:
    .word __stack_top               /* initial SP */
    .word Reset_Handler
    .word fw_default_handler        /* NMI */
    .word fw_default_handler        /* HardFault */
    .word fw_default_handler        /* MemManage */
    .word fw_default_handler        /* BusFault */
    .word fw_default_handler        /* UsageFault */
    .word 0, 0, 0, 0
    .word fw_default_handler        /* SVCall */
    .word fw_default_handler        /* DebugMonitor */
    .word 0
    .word fw_default_handler        /* PendSV */
    .word fw_default_handler        /* SysTick (never enabled: TICKINT = 0) */
    .rept 32
    .word fw_default_handler        /* external interrupts: none enabled */
    .endr
    .size __isr_vector, . - __isr_vector

    .section .text.Reset_Handler,"ax",%progbits
    .global Reset_Handler
    .type Reset_Handler, %function
    .thumb_func
Reset_Handler:
    /* FPU: full access to CP10 and CP11 (CPACR bits 20..23) before any float code. */
    ldr r0, =CPACR
    ldr r1, [r0]
    orr r1, r1, #(0xF << 20)
    str r1, [r0]
    dsb
    isb
    /* .data: copy initial values from flash */
    ldr r0, =_sdata
    ldr r1, =_edata
    ldr r2, =_sidata
1:  cmp r0, r1
    bhs 2f
    ldr r3, [r2], #4
    str r3, [r0], #4
    b 1b
    /* .bss: zero */
2:  ldr r0, =_sbss
    ldr r1, =_ebss
    movs r3, #0
3:  cmp r0, r1
    bhs 4f
    str r3, [r0], #4
    b 3b
    /* stack: paint everything below sp, so even main's own use shows */
4:  ldr r0, =__stack_limit
    mov r1, sp
    ldr r3, =STACK_PATTERN
5:  cmp r0, r1
    bhs 6f
    str r3, [r0], #4
    b 5b
6:  movs r0, #0
    movs r1, #0
    bl main
    bl fw_exit                      /* does not return */
7:  b 7b
    .ltorg
    .size Reset_Handler, . - Reset_Handler

/* Any exception: report its number (IPSR) and exit with an error. */
    .section .text.fw_default_handler,"ax",%progbits
    .global fw_default_handler
    .type fw_default_handler, %function
    .thumb_func
fw_default_handler:
    mrs r0, ipsr
    b fw_fault
    .size fw_default_handler, . - fw_default_handler
