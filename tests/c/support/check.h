/*
 * check.h - the smallest test harness: CHECK macros that report file:line and keep going,
 * and RUN() that prints each test's name. A test program returns check_failures() != 0.
 */
#ifndef LVP_TEST_CHECK_H
#define LVP_TEST_CHECK_H

#include <math.h>
#include <stdio.h>

static int check__failures;

static inline int check_failures(void)
{
	return check__failures;
}

#define CHECK(cond)                                                                                                    \
	do {                                                                                                               \
		if (!(cond)) {                                                                                                 \
			fprintf(stderr, "  FAIL %s:%d: %s\n", __FILE__, __LINE__, #cond);                                          \
			++check__failures;                                                                                         \
		}                                                                                                              \
	} while (0)

/* |a - b| <= tol, printing both values when it fails. */
#define CHECK_NEAR(a, b, tol)                                                                                          \
	do {                                                                                                               \
		double check__a = (double)(a), check__b = (double)(b), check__t = (double)(tol);                               \
		if (!(fabs(check__a - check__b) <= check__t)) {                                                                \
			fprintf(stderr, "  FAIL %s:%d: %s = %.9g, %s = %.9g, tolerance %.3g\n", __FILE__, __LINE__, #a, check__a,  \
			        #b, check__b, check__t);                                                                           \
			++check__failures;                                                                                         \
		}                                                                                                              \
	} while (0)

/* An lvp_result call that must succeed; prints the diagnostic otherwise. */
#define CHECK_OK(call, diag)                                                                                           \
	do {                                                                                                               \
		lvp_result check__r = (call);                                                                                  \
		if (check__r != lvp_success) {                                                                                 \
			fprintf(stderr, "  FAIL %s:%d: %s -> %s: %s\n", __FILE__, __LINE__, #call, lvp_result_name(check__r),      \
			        (diag).message);                                                                                   \
			++check__failures;                                                                                         \
		}                                                                                                              \
	} while (0)

#define RUN(test)                                                                                                      \
	do {                                                                                                               \
		int check__before = check__failures;                                                                           \
		printf("%s\n", #test);                                                                                         \
		fflush(stdout);                                                                                                \
		test();                                                                                                        \
		if (check__failures != check__before)                                                                          \
			printf("  ^ %d check(s) failed\n", check__failures - check__before);                                       \
	} while (0)

#endif
