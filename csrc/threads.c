/*
 * threads.c - a binding's own worker threads (no global pool, no global state): created by
 * lvp_bind() when thread_count > 1, woken for each parallel loop of a frame, joined by
 * lvp_free(). A loop is cut into fixed chunks that the workers and the calling thread take in
 * turn; every chunk writes only its own outputs, so the result does not depend on the thread
 * count or on which thread ran which chunk.
 *
 * A frame runs dozens of loops of a millisecond or less, with a little serial work between them.
 * Waking a sleeping thread costs tens of microseconds, so a worker that finished a loop first
 * watches for the next one for a while (LVP__WATCH_SPINS) before it sleeps; chunks are claimed
 * with one atomic add, not a lock. The lock guards only a loop's set-up and the workers' joining
 * and leaving it: the caller does not set up the next loop before every worker that joined the
 * last has left, so no worker ever claims a chunk of a loop other than the one it read.
 */
#include "threads.h"

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdlib.h>

/* Polls of the loop counter a worker makes before sleeping, about a tenth of a millisecond. */
#define LVP__WATCH_SPINS 4000

struct lvp__pool {
	int32_t worker_count;
	pthread_t *workers;
	pthread_mutex_t lock;
	pthread_cond_t wake, left;
	/* the loop being run: set by the caller under the lock, read by the workers that joined it */
	lvp__task task;
	void *context;
	int32_t item_count, grain, chunk_count;
	atomic_int next_chunk, chunks_done;
	int32_t joined, sleeping; /* under the lock: workers in the loop, workers waiting on wake */
	atomic_uint_fast64_t generation;
	atomic_bool stop;
};

static inline void lvp__cpu_relax(void)
{
#if defined(__x86_64__) || defined(__i386__)
	__builtin_ia32_pause();
#elif defined(__aarch64__)
	__asm__ __volatile__("yield");
#endif
}

/* Takes chunks of the current loop until none is left. */
static void lvp__run_chunks(lvp__pool *pool)
{
	for (;;) {
		int32_t chunk = atomic_fetch_add_explicit(&pool->next_chunk, 1, memory_order_acquire);
		if (chunk >= pool->chunk_count)
			return;
		int32_t begin = chunk * pool->grain;
		int32_t end = begin + pool->grain < pool->item_count ? begin + pool->grain : pool->item_count;
		pool->task(pool->context, begin, end);
		atomic_fetch_add_explicit(&pool->chunks_done, 1, memory_order_release);
	}
}

static void *lvp__worker(void *argument)
{
	lvp__pool *pool = argument;
	uint_fast64_t seen = 0;
	for (;;) {
		for (int spin = 0; spin < LVP__WATCH_SPINS; ++spin) {
			if (atomic_load_explicit(&pool->generation, memory_order_relaxed) != seen ||
			    atomic_load_explicit(&pool->stop, memory_order_relaxed))
				break;
			lvp__cpu_relax();
		}
		pthread_mutex_lock(&pool->lock);
		while (!atomic_load(&pool->stop) && atomic_load(&pool->generation) == seen) {
			++pool->sleeping;
			pthread_cond_wait(&pool->wake, &pool->lock);
			--pool->sleeping;
		}
		if (atomic_load(&pool->stop)) {
			pthread_mutex_unlock(&pool->lock);
			return NULL;
		}
		seen = atomic_load(&pool->generation);
		++pool->joined;
		pthread_mutex_unlock(&pool->lock);
		lvp__run_chunks(pool);
		pthread_mutex_lock(&pool->lock);
		if (--pool->joined == 0)
			pthread_cond_signal(&pool->left);
		pthread_mutex_unlock(&pool->lock);
	}
}

lvp_result lvp__pool_create(lvp__pool **r_pool, int32_t thread_count)
{
	*r_pool = NULL;
	if (thread_count <= 1)
		return lvp_success;
	lvp__pool *pool = calloc(1, sizeof(lvp__pool));
	if (!pool)
		return lvp_error_out_of_memory;
	pool->workers = calloc((size_t)thread_count - 1, sizeof(pthread_t));
	if (!pool->workers) {
		free(pool);
		return lvp_error_out_of_memory;
	}
	if (pthread_mutex_init(&pool->lock, NULL) != 0) {
		free(pool->workers);
		free(pool);
		return lvp_error_thread;
	}
	pthread_cond_init(&pool->wake, NULL);
	pthread_cond_init(&pool->left, NULL);
	atomic_init(&pool->next_chunk, 0);
	atomic_init(&pool->chunks_done, 0);
	atomic_init(&pool->generation, 0);
	atomic_init(&pool->stop, false);
	for (int32_t i = 0; i < thread_count - 1; ++i) {
		if (pthread_create(&pool->workers[i], NULL, lvp__worker, pool) != 0) {
			lvp__pool_destroy(pool);
			return lvp_error_thread;
		}
		pool->worker_count = i + 1;
	}
	*r_pool = pool;
	return lvp_success;
}

void lvp__pool_destroy(lvp__pool *pool)
{
	if (!pool)
		return;
	pthread_mutex_lock(&pool->lock);
	atomic_store(&pool->stop, true);
	pthread_cond_broadcast(&pool->wake);
	pthread_mutex_unlock(&pool->lock);
	for (int32_t i = 0; i < pool->worker_count; ++i)
		pthread_join(pool->workers[i], NULL);
	pthread_cond_destroy(&pool->wake);
	pthread_cond_destroy(&pool->left);
	pthread_mutex_destroy(&pool->lock);
	free(pool->workers);
	free(pool);
}

void lvp__parallel_for(lvp__pool *pool, lvp__task task, void *context, int32_t item_count, int32_t grain)
{
	if (item_count <= 0)
		return;
	if (!pool || item_count <= grain) {
		task(context, 0, item_count);
		return;
	}
	int32_t chunk_count = (int32_t)(((int64_t)item_count + grain - 1) / grain);
	pthread_mutex_lock(&pool->lock);
	/* A worker that joined the last loop after the caller had run all of it (it woke late) may
	 * still be between its join and its claim: it must leave before the fields below change, or
	 * it could pair this loop's chunk count with the last loop's task and context (whose stack may
	 * be gone), or run a chunk of this loop before next_chunk is reset and that chunk again after
	 * (tests/c/test_threads.c). Workers join only under the lock, so once none is joined none
	 * reads these fields before they are all set. */
	while (pool->joined > 0)
		pthread_cond_wait(&pool->left, &pool->lock);
	pool->task = task;
	pool->context = context;
	pool->item_count = item_count;
	pool->grain = grain;
	pool->chunk_count = chunk_count;
	atomic_store(&pool->chunks_done, 0);
	atomic_store(&pool->next_chunk, 0);
	atomic_fetch_add(&pool->generation, 1);
	if (pool->sleeping > 0)
		pthread_cond_broadcast(&pool->wake);
	pthread_mutex_unlock(&pool->lock);
	lvp__run_chunks(pool);
	/* The last chunks are being run by workers: a chunk's time at most. A worker still in this loop
	 * after them reads only its chunk count, and the next loop waits for it to leave. */
	for (int spin = 0; atomic_load_explicit(&pool->chunks_done, memory_order_acquire) < chunk_count; ++spin) {
		if (spin < LVP__WATCH_SPINS)
			lvp__cpu_relax();
		else
			sched_yield();
	}
}
