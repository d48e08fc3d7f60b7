/*
 * test_fuzz_regressions.c - replays, under ASan and UBSan, every input in tests/fuzz/regressions/
 * (inputs that once crashed the fuzzer or broke a contract it checks) and the seed corpus
 * tests/fuzz/corpus/, through the fuzzer's own decoding (tests/fuzz/fuzz_decode.h). A crash
 * found by `./build.sh fuzz` becomes a permanent test by copying the artifact into
 * tests/fuzz/regressions/ under a name that says what it broke. `./build.sh test` runs it
 * twice: built by gcc with the other C tests, and by clang as the fuzzer is (build.sh,
 * run_fuzz_regressions_clang), whose UBSan also flags a zero offset applied to a null pointer.
 *
 * Each input runs in a child process, so that one that still crashes is reported by name and the
 * others still run: a fork on POSIX systems; on Windows, which has no fork, this program again with
 * `--replay FILE` (which replays that one file and exits).
 */
#include "support/check.h"
#include "support/test_meshes.h"

#include "../fuzz/fuzz_decode.h"

#include <dirent.h>
#include <stdlib.h>
#include <string.h>
#if defined(_WIN32)
#include <process.h>
#include <windows.h>
#else
#include <sys/wait.h>
#include <unistd.h>
#endif

/* Replays one input in a child process. Returns 0 when the child finished normally; otherwise
 * fills r_how ("exit status 1", "signal 6") and returns -1. Returns 1 when no child could be
 * started, and the caller replays the input in this process instead. */
static int replay_in_child(const char *path, const uint8_t *data, size_t size, char *r_how, size_t how_size)
{
#if defined(_WIN32)
	(void)data;
	(void)size;
	char self[MAX_PATH];
	DWORD length = GetModuleFileNameA(NULL, self, sizeof(self));
	if (length == 0 || length >= sizeof(self))
		return 1;
	/* _spawnv joins its arguments with spaces: quote them (no Windows path holds a quote). */
	char quoted_self[MAX_PATH + 2], quoted_path[1024 + 2];
	snprintf(quoted_self, sizeof(quoted_self), "\"%s\"", self);
	snprintf(quoted_path, sizeof(quoted_path), "\"%s\"", path);
	const char *arguments[] = {quoted_self, "--replay", quoted_path, NULL};
	intptr_t status = _spawnv(_P_WAIT, self, arguments);
	if (status == -1)
		return 1;
	if (status == 0)
		return 0;
	/* A crash ends the child with its exception code (0xC0000005 for an access violation). */
	snprintf(r_how, how_size, "exit status 0x%lx", (unsigned long)status);
	return -1;
#else
	pid_t child = fork();
	if (child == 0) {
		fuzz_run(data, size);
		fflush(stdout);
		_exit(0);
	}
	int status = 0;
	if (child < 0 || waitpid(child, &status, 0) != child)
		return 1;
	(void)path;
	if (WIFEXITED(status) && WEXITSTATUS(status) == 0)
		return 0;
	snprintf(r_how, how_size, "%s %d", WIFSIGNALED(status) ? "signal" : "exit status",
	         WIFSIGNALED(status) ? WTERMSIG(status) : WEXITSTATUS(status));
	return -1;
#endif
}

static int compare_names(const void *a, const void *b)
{
	return strcmp(*(char *const *)a, *(char *const *)b);
}

/* Replays every regular file of `directory` in name order; returns how many it replayed. */
static int replay_directory(const char *directory)
{
	DIR *dir = opendir(directory);
	if (!dir) {
		fprintf(stderr, "  cannot open %s (the tests run from tests/)\n", directory);
		return -1;
	}
	char **names = NULL;
	int count = 0, capacity = 0;
	for (struct dirent *entry; (entry = readdir(dir));) {
		if (entry->d_name[0] == '.')
			continue; /* ., .. and .gitkeep */
		if (count == capacity) {
			capacity = capacity ? 2 * capacity : 64;
			char **bigger = realloc(names, (size_t)capacity * sizeof(char *));
			if (!bigger)
				abort();
			names = bigger;
		}
		names[count] = strdup(entry->d_name);
		if (!names[count])
			abort();
		++count;
	}
	closedir(dir);
	if (count > 0) /* qsort(NULL, 0, ...) is undefined */
		qsort(names, (size_t)count, sizeof(char *), compare_names);
	int replayed = 0;
	for (int i = 0; i < count; ++i) {
		char path[1024];
		snprintf(path, sizeof(path), "%s/%s", directory, names[i]);
		size_t size = 0;
		char *data = test_read_file(path, &size);
		CHECK(data != NULL);
		if (data) {
			printf("  %s (%zu bytes)\n", path, size);
			fflush(stdout);
			fflush(stderr);
			/* In a child, so that one that still crashes (ASan, UBSan or a contract check
			 * abort) is reported by name and the others still run. */
			char how[64] = "";
			int outcome = replay_in_child(path, (const uint8_t *)data, size, how, sizeof(how));
			if (outcome > 0) {
				fuzz_run((const uint8_t *)data, size); /* no child process: run it here */
			} else if (outcome < 0) {
				fprintf(stderr, "  FAIL %s: still crashes (%s); replay it with the fuzzer: "
				                "build/fuzz/fuzz_lvp tests/%s\n",
				        path, how, path);
				++check__failures;
			}
			++replayed;
		}
		free(data);
		free(names[i]);
	}
	free(names);
	return replayed;
}

static void test_regressions_replay(void)
{
	CHECK(replay_directory("fuzz/regressions") >= 0);
}

static void test_seed_corpus_replays(void)
{
	CHECK(replay_directory("fuzz/corpus") >= 10);
}

static void test_empty_and_tiny_inputs(void)
{
	static const uint8_t bytes[4] = {1, 0, 0, 0};
	fuzz_run(NULL, 0);
	for (size_t n = 0; n <= sizeof(bytes); ++n)
		fuzz_run(bytes, n);
}

/* `--replay FILE`: the child of replay_in_child where there is no fork. */
static int replay_one(const char *path)
{
	size_t size = 0;
	char *data = test_read_file(path, &size);
	if (!data)
		return 2;
	fuzz_run((const uint8_t *)data, size);
	free(data);
	fflush(stdout);
	return 0;
}

int main(int argc, char **argv)
{
	if (argc == 3 && strcmp(argv[1], "--replay") == 0)
		return replay_one(argv[2]);
	RUN(test_regressions_replay);
	RUN(test_seed_corpus_replays);
	RUN(test_empty_and_tiny_inputs);
	return check_failures() != 0;
}
