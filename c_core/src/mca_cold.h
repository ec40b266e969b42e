/* Private to the core sources: MCA_COLD marks a function that runs once or rarely (defaults,
 * configuration checks, init). GCC and Clang then optimise it for size, as -Os would, and
 * keep it out of the hot code's way; the hot paths stay at -O2. It changes no value (the
 * float flags of the build hold for every function). MCA_NOINLINE keeps a function that is
 * called once out of its caller, so the caller's frame does not carry its locals on the other
 * paths (the stack goal is per call chain). */
#ifndef MCA_COLD_H
#define MCA_COLD_H

#if defined(__GNUC__) || defined(__clang__)
#define MCA_COLD __attribute__((cold))
#define MCA_NOINLINE __attribute__((noinline))
#else
#define MCA_COLD
#define MCA_NOINLINE
#endif

#endif /* MCA_COLD_H */
