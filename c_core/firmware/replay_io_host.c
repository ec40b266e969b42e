/*
 * replay_io.h on the host: stdio files, stderr log, no cost counter. The replay program
 * above this shim is the same source the Cortex-M4F runs.
 */
#include <stdio.h>

#include "replay_io.h"

#define FILES_MAX 8

static FILE *files[FILES_MAX];

void rio_init(int *argc, char ***argv)
{
    (void)argc; /* the host has a real command line */
    (void)argv;
}

int rio_open(const char *path, int write)
{
    for (int i = 0; i < FILES_MAX; ++i) {
        if (files[i] == NULL) {
            files[i] = fopen(path, write ? "wb" : "rb");
            return files[i] != NULL ? i : -1;
        }
    }
    return -1;
}

long rio_read(int h, void *buf, size_t n)
{
    const size_t got = fread(buf, 1u, n, files[h]);
    return ferror(files[h]) ? -1 : (long)got;
}

int rio_write(int h, const void *buf, size_t n)
{
    return fwrite(buf, 1u, n, files[h]) == n ? 0 : -1;
}

void rio_close(int h)
{
    (void)fclose(files[h]);
    files[h] = NULL;
}

void rio_log(const char *msg)
{
    (void)fprintf(stderr, "%s\n", msg);
}

int rio_can_measure(void)
{
    return 0;
}

uint32_t rio_instr_per_tick(void)
{
    return 0u;
}

void rio_stack_paint(void)
{
}

uint32_t rio_stack_bytes(void)
{
    return 0u;
}

uint32_t rio_stack_used(void)
{
    return 0u;
}

uint64_t rio_sync(void)
{
    return 0u;
}

uint32_t rio_instructions(uint64_t t0, uint64_t t1, int32_t overhead)
{
    (void)t0;
    (void)t1;
    (void)overhead;
    return 0u;
}

uint32_t rio_ticks(void)
{
    return 0u;
}

void rio_spin(uint32_t n)
{
    (void)n;
}

void rio_nop(void)
{
}
