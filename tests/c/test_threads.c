/*
 * test_threads.c - a binding's worker threads (csrc/threads.c): every chunk of every loop runs exactly once,
 * with that loop's own task and context, whatever the thread count, even when a loop follows the last at
 * once and a worker only wakes for a loop after the caller has run all of it. A frame runs dozens of loops
 * a millisecond, each with its context on the stack of a function that returns: a chunk run twice, or run
 * with the context of a loop that has ended, writes into memory the binding no longer owns (a crash inside
 * Blender).
 *
 * Built as every C test is (AddressSanitizer), and by ./build.sh also under ThreadSanitizer, which reports
 * any access to a loop's fields that the pool's lock and counters do not order (a worker reading a loop's
 * task while the caller sets up the next), whether or not this run's timing made it go wrong.
 */
#include "threads.h"
#include "support/check.h"

#include <stdatomic.h>
#include <stdlib.h>

/* What one loop's chunks see: its id, its item count, and how often each item was visited. */
typedef struct loop_context {
	long id;
	int32_t item_count;
	atomic_int *visits;
} loop_context;

static atomic_long running_loop;
static atomic_long wrong_context, out_of_range, visited_twice;

static void visit(void *context, int32_t begin, int32_t end)
{
	const loop_context *loop = context;
	if (loop->id != atomic_load(&running_loop))
		atomic_fetch_add(&wrong_context, 1);
	if (begin < 0 || end > loop->item_count || begin >= end) {
		atomic_fetch_add(&out_of_range, 1);
		return;
	}
	for (int32_t i = begin; i < end; ++i)
		if (atomic_fetch_add(&loop->visits[i], 1) != 0)
			atomic_fetch_add(&visited_twice, 1);
}

/* One loop with its context on this function's stack, which ends with it; returns the items not visited. */
static int32_t run_loop(lvp__pool *pool, long id, int32_t item_count, int32_t grain)
{
	atomic_int visits[64];
	for (int32_t i = 0; i < 64; ++i)
		atomic_init(&visits[i], 0);
	loop_context loop = {id, item_count, visits};
	atomic_store(&running_loop, id);
	lvp__parallel_for(pool, visit, &loop, item_count, grain);
	int32_t missed = 0;
	for (int32_t i = 0; i < item_count; ++i)
		missed += atomic_load(&visits[i]) == 0;
	loop.id = -1; /* a chunk run after this reads a context that says so */
	return missed;
}

/* Loops of 2 to 56 items in chunks of one to three, back to back: most are over before a sleeping worker
 * wakes, so workers keep joining loops late. */
static void test_every_chunk_once(int32_t thread_count, long loops)
{
	lvp__pool *pool = NULL;
	CHECK(lvp__pool_create(&pool, thread_count) == lvp_success);
	CHECK(pool != NULL);
	atomic_store(&wrong_context, 0);
	atomic_store(&out_of_range, 0);
	atomic_store(&visited_twice, 0);
	long missed = 0;
	for (long i = 0; i < loops && pool; ++i)
		missed += run_loop(pool, i, 2 + (int32_t)(i % 7) * 9, 1 + (int32_t)(i % 3));
	lvp__pool_destroy(pool);
	printf("  %d threads, %ld loops: items missed %ld, run twice %ld, with another loop's context %ld, out of range "
	       "%ld\n",
	       (int)thread_count, loops, missed, (long)visited_twice, (long)wrong_context, (long)out_of_range);
	CHECK(missed == 0);
	CHECK(atomic_load(&visited_twice) == 0);
	CHECK(atomic_load(&wrong_context) == 0);
	CHECK(atomic_load(&out_of_range) == 0);
}

static void test_two_threads(void)
{
	test_every_chunk_once(2, 50000);
}

static void test_four_threads(void)
{
	test_every_chunk_once(4, 25000);
}

/* One thread has no pool: the loop runs on the caller, whole. */
static void test_one_thread(void)
{
	lvp__pool *pool = (lvp__pool *)&pool;
	CHECK(lvp__pool_create(&pool, 1) == lvp_success);
	CHECK(pool == NULL);
	CHECK(run_loop(NULL, 7, 40, 3) == 0);
	CHECK(atomic_load(&visited_twice) == 0 && atomic_load(&wrong_context) == 0);
}

int main(void)
{
	RUN(test_one_thread);
	RUN(test_two_threads);
	RUN(test_four_threads);
	return check_failures() != 0;
}
