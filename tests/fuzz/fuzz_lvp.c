/*
 * fuzz_lvp.c - libFuzzer target over the whole public API of lvp.h: bind, the per-frame
 * correction, the map change, segmentation and map queries, both skinnings, automatic weights
 * and the mesh geometry helpers. The decoding and the calls are in fuzz_decode.h, shared with
 * tests/c/test_fuzz_regressions.c. Run: ./build.sh fuzz [seconds].
 */
#include "fuzz_decode.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	fuzz_run(data, size);
	return 0;
}
