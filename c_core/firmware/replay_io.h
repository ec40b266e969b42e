/**
 * @file replay_io.h
 * @brief The tiny platform shim under replay_main.c: files, log, exit, and cost measurement.
 *
 * Two implementations, one program:
 *  - replay_io_host.c: stdio, no cost counter (every count is 0);
 *  - replay_io_semihost.c + fw_measure.S + startup_m4f.S: Arm semihosting (bkpt 0xab) on
 *    the Cortex-M4F under QEMU, instructions from SysTick under -icount shift=0, stack
 *    high-water by painting.
 */
#ifndef MCA_REPLAY_IO_H
#define MCA_REPLAY_IO_H

#include <stddef.h>
#include <stdint.h>

/** Set up the platform; on the target, fill argc/argv from the semihosting command line. */
void rio_init(int *argc, char ***argv);

/** Open path for binary reading (write = 0) or writing (write = 1). @return handle, < 0 on error. */
int rio_open(const char *path, int write);

/** Read up to n bytes. @return bytes read (0 at end of file), < 0 on error. */
long rio_read(int h, void *buf, size_t n);

/** Write n bytes. @return 0, or < 0 on error. */
int rio_write(int h, const void *buf, size_t n);

void rio_close(int h);

/** One line of text to the console (stderr on the host). */
void rio_log(const char *msg);

/** 1 when rio_sync/rio_stack_used measure something (the target), 0 on the host. */
int rio_can_measure(void);

/** Instructions per SysTick tick the measurement assumes (0 on the host). */
uint32_t rio_instr_per_tick(void);

/**
 * Paint the stack from its limit up to the caller's stack pointer. Uses no stack itself,
 * so it is called right before the measured call.
 */
void rio_stack_paint(void);

/** Size of the painted stack region in bytes (0 on the host). */
uint32_t rio_stack_bytes(void);

/** Bytes of stack below the stack pointer of the last rio_stack_paint() that were written. */
uint32_t rio_stack_used(void);

/**
 * Wait for a SysTick edge and return a time stamp aligned to it (target; 0 on the host).
 * Two stamps around a call give its instructions via rio_instructions(). Uses no stack.
 */
uint64_t rio_sync(void);

/**
 * Instructions between two rio_sync() stamps, less `overhead` (calibrated on an empty call;
 * it may be negative, the stamps' own constant being so). Never below 0.
 */
uint32_t rio_instructions(uint64_t t0, uint64_t t1, int32_t overhead);

/** SysTick's current value (counts down, 24 bits), read plainly; 0 on the host. */
uint32_t rio_ticks(void);

/** A known instruction sequence for calibration: exactly 2n + 1 instructions (n >= 1). */
void rio_spin(uint32_t n);

/** An empty function (one instruction, bx lr): what a measured call costs with nothing in it. */
void rio_nop(void);

#endif /* MCA_REPLAY_IO_H */
