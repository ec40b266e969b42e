/*
 * replay_io.h on the Cortex-M4F under QEMU: Arm semihosting (bkpt 0xab, the M-profile
 * trap) for files, console and exit; SysTick for instruction counts (fw_measure.S).
 * QEMU: -semihosting-config enable=on,target=native; relative paths resolve in QEMU's
 * working directory.
 */
#include <string.h>

#include "replay_io.h"

/* Semihosting operation numbers (Arm "Semihosting for AArch32 and AArch64", v3). */
#define SYS_OPEN 0x01
#define SYS_CLOSE 0x02
#define SYS_WRITE0 0x04
#define SYS_WRITE 0x05
#define SYS_READ 0x06
#define SYS_GET_CMDLINE 0x15
#define SYS_EXIT 0x18
#define SYS_EXIT_EXTENDED 0x20
#define ADP_STOPPED_APPLICATION_EXIT 0x20026u
#define SH_MODE_RB 1  /* fopen "rb" */
#define SH_MODE_WB 5  /* fopen "wb" */

/* SysTick (Armv7-M ARM B3.3). CLKSOURCE = 1: the processor clock, 25 MHz on mps2-an386. */
#define SYST_CSR (*(volatile uint32_t *)0xE000E010u)
#define SYST_RVR (*(volatile uint32_t *)0xE000E014u)
#define SYST_CVR (*(volatile uint32_t *)0xE000E018u)
#define SYST_CSR_ENABLE 1u
#define SYST_CSR_CLKSOURCE 4u

/* -icount shift=0: 1 ns per instruction; 25 MHz SysTick: 40 ns per tick. */
#define INSTR_PER_TICK 40u
/* rio_sync's loop: INSTR_PER_TICK + 1 instructions per iteration (fw_measure.S). */
#define VERNIER_LOOP 41u

#define CMDLINE_MAX 1024
#define ARGV_MAX 8

void fw_exit(int code) __attribute__((noreturn));
void fw_fault(uint32_t ipsr) __attribute__((noreturn));

static int sh_call(int op, const void *arg)
{
    register int r0 __asm__("r0") = op;
    register const void *r1 __asm__("r1") = arg;
    __asm__ volatile("bkpt 0xab" : "+r"(r0) : "r"(r1) : "memory");
    return r0;
}

static char cmdline[CMDLINE_MAX];
static char *args[ARGV_MAX + 1];

void rio_init(int *argc, char ***argv)
{
    SYST_CSR = 0u;
    SYST_RVR = 0x00FFFFFFu; /* full 24-bit period: 2^24 ticks, 0.67 s of virtual time */
    SYST_CVR = 0u;          /* any write clears the counter */
    SYST_CSR = SYST_CSR_CLKSOURCE | SYST_CSR_ENABLE;

    struct {
        char *buf;
        int len;
    } blk = {cmdline, CMDLINE_MAX - 1};
    int n = 0;
    if (sh_call(SYS_GET_CMDLINE, &blk) == 0) {
        cmdline[blk.len] = '\0';
        char *p = cmdline;
        while (*p != '\0' && n < ARGV_MAX) {
            while (*p == ' ') {
                *p++ = '\0';
            }
            if (*p == '\0') {
                break;
            }
            args[n++] = p;
            while (*p != '\0' && *p != ' ') {
                ++p;
            }
        }
    }
    args[n] = NULL;
    *argc = n;
    *argv = args;
}

int rio_open(const char *path, int write)
{
    const struct {
        const char *name;
        int mode;
        size_t len;
    } blk = {path, write ? SH_MODE_WB : SH_MODE_RB, strlen(path)};
    return sh_call(SYS_OPEN, &blk);
}

long rio_read(int h, void *buf, size_t n)
{
    const struct {
        int h;
        void *buf;
        size_t n;
    } blk = {h, buf, n};
    const int left = sh_call(SYS_READ, &blk); /* bytes NOT read */
    if (left < 0 || (size_t)left > n) {
        return -1;
    }
    return (long)(n - (size_t)left);
}

int rio_write(int h, const void *buf, size_t n)
{
    const struct {
        int h;
        const void *buf;
        size_t n;
    } blk = {h, buf, n};
    return sh_call(SYS_WRITE, &blk) == 0 ? 0 : -1;
}

void rio_close(int h)
{
    const int blk = h;
    (void)sh_call(SYS_CLOSE, &blk);
}

void rio_log(const char *msg)
{
    (void)sh_call(SYS_WRITE0, msg);
    (void)sh_call(SYS_WRITE0, "\n");
}

int rio_can_measure(void)
{
    return 1;
}

uint32_t rio_instr_per_tick(void)
{
    return INSTR_PER_TICK;
}

extern uint32_t __stack_limit[], __stack_top[]; /* mps2_an386.ld */

uint32_t rio_stack_bytes(void)
{
    return (uint32_t)((uintptr_t)__stack_top - (uintptr_t)__stack_limit);
}

uint32_t rio_ticks(void)
{
    return SYST_CVR & 0x00FFFFFFu;
}

uint32_t rio_instructions(uint64_t t0, uint64_t t1, int32_t overhead)
{
    /* Both stamps sit on a tick's first instruction: their distance is whole ticks; the
     * second stamp's own loop iterations are not the call's. */
    const int64_t ticks = (int64_t)(((uint32_t)t0 - (uint32_t)t1) & 0x00FFFFFFu);
    const int64_t iters = (int64_t)(t1 >> 32);
    const int64_t n = ticks * INSTR_PER_TICK - (int64_t)VERNIER_LOOP * iters - overhead;
    return n > 0 ? (uint32_t)n : 0u;
}

void fw_exit(int code)
{
    const uint32_t blk[2] = {ADP_STOPPED_APPLICATION_EXIT, (uint32_t)code};
    (void)sh_call(SYS_EXIT_EXTENDED, blk);
    /* Fallback for a host without the extension: plain exit (status 0 or 1 only). */
    (void)sh_call(SYS_EXIT, (const void *)(code == 0 ? ADP_STOPPED_APPLICATION_EXIT : 0x20023u));
    for (;;) {
    }
}

void fw_fault(uint32_t ipsr)
{
    static const char hex[] = "0123456789abcdef";
    char msg[] = "fw: exception 0x00, stopping";
    msg[16] = hex[(ipsr >> 4) & 0xFu];
    msg[17] = hex[ipsr & 0xFu];
    rio_log(msg);
    fw_exit(70);
}
