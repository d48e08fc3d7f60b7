/*
 * threads.c - a binding's own worker threads (no global pool, no global state): created by
 * lvp_bind() when thread_count > 1, woken for each parallel loop of a frame, joined by
 * lvp_free(). A loop is cut into fixed chunks that the workers and the calling thread take in
 * turn; every chunk writes only its own outputs, so the result does not depend on the thread
 * count or on which thread ran which chunk.
 */
#include "threads.h"

#include <pthread.h>
#include <stdlib.h>

struct lvp__pool {
	int32_t worker_count;
	pthread_t *workers;
	pthread_mutex_t lock;
	pthread_cond_t wake, finished;
	/* the loop being run */
	lvp__task task;
	void *context;
	int32_t item_count, grain, next_chunk, chunk_count, chunks_done;
	uint64_t generation;
	bool stop;
};

/* Takes chunks until none is left; called with the lock held, returns with it held. */
static void lvp__run_chunks(lvp__pool *pool)
{
	while (pool->next_chunk < pool->chunk_count) {
		int32_t chunk = pool->next_chunk++;
		lvp__task task = pool->task;
		void *context = pool->context;
		int32_t begin = chunk * pool->grain;
		int32_t end = begin + pool->grain < pool->item_count ? begin + pool->grain : pool->item_count;
		pthread_mutex_unlock(&pool->lock);
		task(context, begin, end);
		pthread_mutex_lock(&pool->lock);
		if (++pool->chunks_done == pool->chunk_count)
			pthread_cond_broadcast(&pool->finished);
	}
}

static void *lvp__worker(void *argument)
{
	lvp__pool *pool = argument;
	uint64_t seen = 0;
	pthread_mutex_lock(&pool->lock);
	for (;;) {
		while (!pool->stop && pool->generation == seen)
			pthread_cond_wait(&pool->wake, &pool->lock);
		if (pool->stop)
			break;
		seen = pool->generation;
		lvp__run_chunks(pool);
	}
	pthread_mutex_unlock(&pool->lock);
	return NULL;
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
	pthread_cond_init(&pool->finished, NULL);
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
	pool->stop = true;
	pthread_cond_broadcast(&pool->wake);
	pthread_mutex_unlock(&pool->lock);
	for (int32_t i = 0; i < pool->worker_count; ++i)
		pthread_join(pool->workers[i], NULL);
	pthread_cond_destroy(&pool->wake);
	pthread_cond_destroy(&pool->finished);
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
	pthread_mutex_lock(&pool->lock);
	pool->task = task;
	pool->context = context;
	pool->item_count = item_count;
	pool->grain = grain;
	pool->next_chunk = 0;
	pool->chunks_done = 0;
	pool->chunk_count = (int32_t)(((int64_t)item_count + grain - 1) / grain);
	++pool->generation;
	pthread_cond_broadcast(&pool->wake);
	lvp__run_chunks(pool);
	while (pool->chunks_done < pool->chunk_count)
		pthread_cond_wait(&pool->finished, &pool->lock);
	pthread_mutex_unlock(&pool->lock);
}
