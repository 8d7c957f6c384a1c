/* Minimal test helpers shared by all sooc3d tests.
 * A test program counts failures and returns non-zero if any check failed.
 * Return SOOC_TEST_SKIP (77) to tell CTest the test was skipped. */
#ifndef SOOC3D_TEST_CHECK_H
#define SOOC3D_TEST_CHECK_H

#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#define SOOC_TEST_SKIP 77

static int g_check_fail = 0, g_check_n = 0;

#define CHECK(cond)                                                                    \
    do {                                                                               \
        g_check_n++;                                                                   \
        if (!(cond)) {                                                                 \
            g_check_fail++;                                                            \
            fprintf(stderr, "%s:%d: CHECK failed: %s\n", __FILE__, __LINE__, #cond);   \
        }                                                                              \
    } while (0)

#define CHECK_MSG(cond, ...)                                                           \
    do {                                                                               \
        g_check_n++;                                                                   \
        if (!(cond)) {                                                                 \
            g_check_fail++;                                                            \
            fprintf(stderr, "%s:%d: CHECK failed: %s: ", __FILE__, __LINE__, #cond);   \
            fprintf(stderr, __VA_ARGS__);                                              \
            fputc('\n', stderr);                                                       \
        }                                                                              \
    } while (0)

/* gamma_n = n u / (1 - n u), u = 2^-24: a float32 sum of n products in any
 * order lies within gamma_n sum |terms| of the exact value (Higham, Accuracy
 * and Stability of Numerical Algorithms, 2nd ed., eq. 3.5). */
static inline double check_gamma_n(double n) { return n / 16777216.0 / (1.0 - n / 16777216.0); }

/* |a - b| <= atol + rtol * max(|a|, |b|) */
#define CHECK_CLOSE(a, b, atol, rtol)                                                  \
    do {                                                                               \
        double ca_ = (double)(a), cb_ = (double)(b);                                   \
        double m_ = fabs(ca_) > fabs(cb_) ? fabs(ca_) : fabs(cb_);                     \
        CHECK_MSG(fabs(ca_ - cb_) <= (atol) + (rtol) * m_, "%s = %.9g, %s = %.9g", #a, \
                  ca_, #b, cb_);                                                       \
    } while (0)

/* Status check: prints sooc_errmsg() on failure. */
#define CHECK_OK(expr)                                                                 \
    do {                                                                               \
        sooc_status s_ = (expr);                                                       \
        CHECK_MSG(s_ == SOOC_OK, "%s -> %s: %s", #expr, sooc_status_str(s_),           \
                  sooc_errmsg());                                                      \
    } while (0)

static inline int check_report(const char *name) {
    if (g_check_fail) {
        fprintf(stderr, "%s: %d of %d checks FAILED\n", name, g_check_fail, g_check_n);
        return 1;
    }
    printf("%s: all %d checks passed\n", name, g_check_n);
    return 0;
}

#endif
