/* A few check macros for the host C unit tests; each test program returns non-zero on failure. */
#ifndef MCA_TEST_H
#define MCA_TEST_H

#include <math.h>
#include <stdio.h>

static int mca_test_failures;

#define CHECK(cond)                                                                  \
    do {                                                                             \
        if (!(cond)) {                                                               \
            ++mca_test_failures;                                                     \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond); \
        }                                                                            \
    } while (0)

#define CHECK_EQ_INT(a, b) CHECK((long)(a) == (long)(b))

#define CHECK_CLOSE(a, b, tol)                                                                  \
    do {                                                                                        \
        const double a_ = (double)(a), b_ = (double)(b);                                        \
        if (!(fabs(a_ - b_) <= (double)(tol))) {                                                \
            ++mca_test_failures;                                                                \
            fprintf(stderr, "%s:%d: %s = %.9g, %s = %.9g, tol %.3g\n", __FILE__, __LINE__, #a, a_, \
                    #b, b_, (double)(tol));                                                     \
        }                                                                                       \
    } while (0)

#define TEST_MAIN_END()                                                 \
    do {                                                                \
        if (mca_test_failures) {                                        \
            fprintf(stderr, "%d check(s) failed\n", mca_test_failures); \
            return 1;                                                   \
        }                                                               \
        printf("all checks passed\n");                                  \
        return 0;                                                       \
    } while (0)

#endif
