/*
 * check.h - the smallest test harness: CHECK macros that report file:line and keep going,
 * and RUN() that prints each test's name. A test program returns check_failures() != 0.
 */
#ifndef LVP_TEST_CHECK_H
#define LVP_TEST_CHECK_H

#include "lvp.h"

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

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

/* Counts a failure of `what` at file:line when !ok, as CHECK does at the caller's line. */
static inline bool check__report(bool ok, const char *what, const char *file, int line)
{
	if (!ok) {
		fprintf(stderr, "  FAIL %s:%d: %s\n", file, line, what);
		++check__failures;
	}
	return ok;
}

static inline void check__error(lvp_result got, const lvp_diagnostic *diag, lvp_result want, const char *argument,
                                int64_t index, const char *file, int line)
{
	if (!check__report(got == want, "got == want", file, line))
		fprintf(stderr, "    got %s, want %s\n", lvp_result_name(got), lvp_result_name(want));
	check__report(diag->argument && strcmp(diag->argument, argument) == 0,
	              "diag->argument && strcmp(diag->argument, argument) == 0", file, line);
	if (diag->argument && strcmp(diag->argument, argument) != 0)
		fprintf(stderr, "    argument %s, want %s\n", diag->argument, argument);
	check__report(diag->index == index, "diag->index == index", file, line);
	check__report(strlen(diag->message) > 10, "strlen(diag->message) > 10", file, line);
}

/* A call that must fail with `want` and a diagnostic that names `argument` and `index` (-1: no item) in a
 * sentence. */
#define CHECK_ERROR(got, diag, want, argument, index)                                                                  \
	check__error((got), (diag), (want), (argument), (index), __FILE__, __LINE__)

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
