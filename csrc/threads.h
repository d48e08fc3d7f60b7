/*
 * threads.h - the worker threads a binding may own (see threads.c). Internal.
 */
#ifndef LVP_THREADS_H
#define LVP_THREADS_H

#include "lvp_internal.h"

typedef struct lvp__pool lvp__pool;

/* A loop body over items [begin, end). */
typedef void (*lvp__task)(void *context, int32_t begin, int32_t end);

/* thread_count - 1 workers (the caller is the last thread); *r_pool = NULL for one thread. */
lvp_result lvp__pool_create(lvp__pool **r_pool, int32_t thread_count);
void lvp__pool_destroy(lvp__pool *pool);

/* Runs task over [0, item_count) in chunks of `grain` items, on the pool's workers and the
 * calling thread; serially when pool is NULL or the loop is a single chunk. */
void lvp__parallel_for(lvp__pool *pool, lvp__task task, void *context, int32_t item_count, int32_t grain);

#endif
