/*
 * giraffe_loader.c - loads the giraffe of tests/data/giraffe (Damien Rohmer's rig of the paper's
 * model; file formats in its README.md) into a test_rig.
 *
 * Mesh: the OBJ's `v` lines in order (vertex k is the k-th `v`), its faces (quads and n-gons up
 * to 9 sides) split into fans from their first corner. The faces wind inward, so after the fan
 * split the winding is flipped whenever the signed volume comes out negative: the rig always
 * has a positive volume.
 *
 * Skeleton: the file gives joints, frames relative to their parent (translation, then rotation
 * as a quaternion x y z w). Bone j is joint j: same index, same parent, same weights.
 *   - rest_matrices[j] is joint j's world frame. The rig comes from Maya, whose joints aim
 *     their local X axis down the bone (towards -X on the mirrored right side), not Blender's
 *     +Y. That does not matter to the core, which only uses T_i * rest_i^-1 and the local frame
 *     to cancel a bone's rigid motion; test_pose() rotation axes for the giraffe are therefore
 *     given in the joint frame (X along the bone).
 *   - heads[j] is joint j's world position.
 *   - tails[j] is the head of joint j's child. With several children (the pelvis: spine, two
 *     hips, sacrum; the top of the spine: neck and two shoulder blades; the head: its end and
 *     the jaw), the child whose head lies farthest along joint j's own +X axis, which Maya aims
 *     down the main bone: this picks the spine, the neck and the head's end. (The farthest head
 *     would pick a shoulder blade for the spine; the average of the heads is a short stub
 *     pointing nowhere.) A joint without children (the `_end` joints, which carry no weight)
 *     continues its parent's bone: tail = head + (head - parent head) / 2.
 *   - Several joints coincide with their only child (the `gi_T_*` helpers, `gi_root`): their
 *     bones have zero length, which lvp.h treats as points; none of them carries weight.
 */
#include "support/test_meshes.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static void *test__giraffe_alloc(size_t count, size_t size)
{
	void *p = calloc(count ? count : 1, size);
	if (!p) {
		fprintf(stderr, "test_load_giraffe: out of memory\n");
		abort();
	}
	return p;
}

static char *test__giraffe_read(const char *directory, const char *name)
{
	char path[1024];
	snprintf(path, sizeof(path), "%s/%s", directory, name);
	char *text = test_read_file(path, NULL);
	if (!text)
		fprintf(stderr, "test_load_giraffe: cannot read %s\n", path);
	return text;
}

/* Reads up to `count` whitespace-separated numbers from *cursor; returns how many it read. */
static int test__read_doubles(double *r_values, int count, char **cursor)
{
	int n = 0;
	while (n < count) {
		char *end;
		double v = strtod(*cursor, &end);
		if (end == *cursor)
			break;
		r_values[n++] = v;
		*cursor = end;
	}
	return n;
}

/* Returns the next line (NUL-terminated in place) and advances *cursor; NULL at the end. */
static char *test__next_line(char **cursor)
{
	char *line = *cursor;
	if (!line || !*line)
		return NULL;
	char *newline = strchr(line, '\n');
	if (newline) {
		*newline = '\0';
		*cursor = newline + 1;
	} else {
		*cursor = line + strlen(line);
	}
	return line;
}

static int test__load_obj(test_rig *rig, char *text)
{
	/* Two passes: count, then fill. */
	int32_t vertex_count = 0, triangle_count = 0;
	for (char *line = text; *line;) {
		if (line[0] == 'v' && line[1] == ' ')
			++vertex_count;
		else if (line[0] == 'f' && line[1] == ' ') {
			int corners = 0;
			for (char *c = line + 1; *c && *c != '\n';) {
				while (*c == ' ' || *c == '\t' || *c == '\r')
					++c;
				if (!*c || *c == '\n')
					break;
				++corners;
				while (*c && *c != ' ' && *c != '\t' && *c != '\r' && *c != '\n')
					++c;
			}
			if (corners >= 3)
				triangle_count += corners - 2;
		}
		char *newline = strchr(line, '\n');
		line = newline ? newline + 1 : line + strlen(line);
	}
	if (vertex_count == 0 || triangle_count == 0)
		return -1;
	rig->vertex_count = vertex_count;
	rig->triangle_count = triangle_count;
	rig->positions = test__giraffe_alloc((size_t)vertex_count * 3, sizeof(float));
	rig->triangles = test__giraffe_alloc((size_t)triangle_count * 3, sizeof(int32_t));
	int32_t v = 0, t = 0;
	char *cursor = text;
	for (char *line; (line = test__next_line(&cursor));) {
		if (line[0] == 'v' && line[1] == ' ') {
			double xyz[3];
			char *c = line + 2;
			if (test__read_doubles(xyz, 3, &c) != 3)
				return -1;
			for (int i = 0; i < 3; ++i)
				rig->positions[3 * v + i] = (float)xyz[i];
			++v;
		} else if (line[0] == 'f' && line[1] == ' ') {
			int32_t first = -1, previous = -1, corner = 0;
			for (char *c = line + 2; *c;) {
				while (*c == ' ' || *c == '\t' || *c == '\r')
					++c;
				if (!*c)
					break;
				char *end;
				long index = strtol(c, &end, 10);
				if (end == c)
					return -1;
				/* OBJ indices are 1-based; negative ones count back from the last vertex read. */
				long k = index > 0 ? index - 1 : v + index;
				if (index == 0 || k < 0 || k >= vertex_count)
					return -1;
				c = end;
				while (*c && *c != ' ' && *c != '\t' && *c != '\r')
					++c; /* skip /vt/vn */
				if (corner++ == 0)
					first = (int32_t)k;
				else if (corner >= 3) {
					rig->triangles[3 * t + 0] = first;
					rig->triangles[3 * t + 1] = previous;
					rig->triangles[3 * t + 2] = (int32_t)k;
					++t;
				}
				previous = (int32_t)k;
			}
		}
	}
	if (v != vertex_count || t != triangle_count)
		return -1;
	double volume = 0.0;
	for (int32_t i = 0; i < t; ++i) {
		const float *a = rig->positions + 3 * rig->triangles[3 * i];
		const float *b = rig->positions + 3 * rig->triangles[3 * i + 1];
		const float *c = rig->positions + 3 * rig->triangles[3 * i + 2];
		volume += a[0] * ((double)b[1] * c[2] - (double)b[2] * c[1]);
		volume += a[1] * ((double)b[2] * c[0] - (double)b[0] * c[2]);
		volume += a[2] * ((double)b[0] * c[1] - (double)b[1] * c[0]);
	}
	if (volume < 0.0)
		for (int32_t i = 0; i < t; ++i) {
			int32_t swap = rig->triangles[3 * i + 1];
			rig->triangles[3 * i + 1] = rig->triangles[3 * i + 2];
			rig->triangles[3 * i + 2] = swap;
		}
	return 0;
}

static int test__load_skeleton(test_rig *rig, char *names, char *parents, char *translations, char *rotations)
{
	int32_t b = 0;
	for (char *c = names, *line; (line = test__next_line(&c));)
		if (line[strspn(line, " \t\r")])
			++b;
	if (b == 0)
		return -1;
	rig->bone_count = b;
	rig->names = test__giraffe_alloc((size_t)b, sizeof(*rig->names));
	rig->parents = test__giraffe_alloc((size_t)b, sizeof(int32_t));
	rig->rest_matrices = test__giraffe_alloc((size_t)b * 16, sizeof(float));
	rig->heads = test__giraffe_alloc((size_t)b * 3, sizeof(float));
	rig->tails = test__giraffe_alloc((size_t)b * 3, sizeof(float));
	/* test__next_line cut the names in place: walk the NUL-separated lines again. */
	char *name = names;
	for (int32_t j = 0; j < b; ++j) {
		while (!name[strspn(name, " \t\r")])
			name += strlen(name) + 1;
		name += strspn(name, " \t\r");
		size_t len = strcspn(name, " \t\r");
		if (len >= sizeof(rig->names[j]))
			len = sizeof(rig->names[j]) - 1;
		memcpy(rig->names[j], name, len);
		rig->names[j][len] = '\0';
		name += strlen(name) + 1;
	}
	double *world = test__giraffe_alloc((size_t)b * 16, sizeof(double));
	for (int32_t j = 0; j < b; ++j) {
		double parent, t[3], q[4];
		if (test__read_doubles(&parent, 1, &parents) != 1 || test__read_doubles(t, 3, &translations) != 3 ||
		    test__read_doubles(q, 4, &rotations) != 4)
			goto fail;
		int32_t p = (int32_t)parent;
		/* The world frames are built in one pass, so a parent must come before its child. */
		if (p < -1 || p >= j)
			goto fail;
		rig->parents[j] = p;
		double n = sqrt(q[0] * q[0] + q[1] * q[1] + q[2] * q[2] + q[3] * q[3]);
		if (!(n > 0.0))
			goto fail;
		double x = q[0] / n, y = q[1] / n, z = q[2] / n, w = q[3] / n;
		double local[16] = {
		    1 - 2 * (y * y + z * z), 2 * (x * y - z * w),     2 * (x * z + y * w),     t[0],
		    2 * (x * y + z * w),     1 - 2 * (x * x + z * z), 2 * (y * z - x * w),     t[1],
		    2 * (x * z - y * w),     2 * (y * z + x * w),     1 - 2 * (x * x + y * y), t[2],
		    0,                       0,                       0,                       1,
		};
		if (p < 0)
			memcpy(world + 16 * j, local, sizeof(local));
		else
			test_multiply_matrices_double(world + 16 * j, world + 16 * p, local);
		for (int k = 0; k < 16; ++k)
			rig->rest_matrices[16 * j + k] = (float)world[16 * j + k];
		for (int i = 0; i < 3; ++i)
			rig->heads[3 * j + i] = (float)world[16 * j + 4 * i + 3];
	}
	for (int32_t j = 0; j < b; ++j) {
		const double *m = world + 16 * j;
		int32_t best = -1;
		double best_along = 0.0;
		for (int32_t c = j + 1; c < b; ++c) {
			if (rig->parents[c] != j)
				continue;
			/* Distance of the child's head along joint j's world X axis (column 0). */
			double along = 0.0;
			for (int i = 0; i < 3; ++i)
				along += m[4 * i] * (world[16 * c + 4 * i + 3] - m[4 * i + 3]);
			if (best < 0 || along > best_along)
				best = c, best_along = along;
		}
		for (int i = 0; i < 3; ++i) {
			double head = world[16 * j + 4 * i + 3], tail;
			if (best >= 0)
				tail = world[16 * best + 4 * i + 3];
			else if (rig->parents[j] >= 0)
				tail = head + 0.5 * (head - world[16 * rig->parents[j] + 4 * i + 3]);
			else
				tail = head;
			rig->tails[3 * j + i] = (float)tail;
		}
	}
	free(world);
	return 0;
fail:
	free(world);
	return -1;
}

static int test__load_weights(test_rig *rig, char *joints, char *weights)
{
	int32_t n = rig->vertex_count;
	/* Count the influences first: every number in rig_joint is one. */
	int64_t count = 0;
	for (char *c = joints;;) {
		double x;
		if (test__read_doubles(&x, 1, &c) != 1)
			break;
		++count;
	}
	if (count > INT32_MAX)
		return -1;
	rig->weight_offsets = test__giraffe_alloc((size_t)n + 1, sizeof(int32_t));
	rig->weight_bones = test__giraffe_alloc((size_t)count, sizeof(int32_t));
	rig->weight_values = test__giraffe_alloc((size_t)count, sizeof(float));
	int32_t used = 0;
	for (int32_t k = 0; k < n; ++k) {
		char *joint_line = test__next_line(&joints), *weight_line = test__next_line(&weights);
		if (!joint_line || !weight_line)
			return -1;
		rig->weight_offsets[k] = used;
		for (;;) {
			double bone, value;
			int got_bone = test__read_doubles(&bone, 1, &joint_line);
			int got_value = test__read_doubles(&value, 1, &weight_line);
			if (got_bone != got_value)
				return -1; /* the two files disagree on this vertex */
			if (!got_bone)
				break;
			if (bone < 0 || bone >= rig->bone_count || used >= count)
				return -1;
			rig->weight_bones[used] = (int32_t)bone;
			rig->weight_values[used++] = (float)value;
		}
	}
	rig->weight_offsets[n] = used;
	return 0;
}

int test_load_giraffe(test_rig *r_rig, const char *directory)
{
	static const char *const files[] = {"mesh.obj",
	                                    "skeleton_joint_name",
	                                    "skeleton_connectivity_parent",
	                                    "skeleton_rest_pose_translation",
	                                    "skeleton_rest_pose_rotation",
	                                    "rig_joint",
	                                    "rig_weights"};
	enum { file_count = sizeof(files) / sizeof(files[0]) };
	char *text[file_count] = {0};
	test_rig rig;
	memset(&rig, 0, sizeof(rig));
	int status = 0;
	for (int i = 0; i < file_count && status == 0; ++i)
		if (!(text[i] = test__giraffe_read(directory, files[i])))
			status = -1;
	if (status == 0 && test__load_obj(&rig, text[0]) != 0) {
		fprintf(stderr, "test_load_giraffe: %s/mesh.obj is malformed\n", directory);
		status = -1;
	}
	if (status == 0 && test__load_skeleton(&rig, text[1], text[2], text[3], text[4]) != 0) {
		fprintf(stderr, "test_load_giraffe: the skeleton files in %s are malformed\n", directory);
		status = -1;
	}
	if (status == 0 && test__load_weights(&rig, text[5], text[6]) != 0) {
		fprintf(stderr, "test_load_giraffe: rig_joint/rig_weights in %s are malformed\n", directory);
		status = -1;
	}
	for (int i = 0; i < file_count; ++i)
		free(text[i]);
	if (status != 0) {
		test_rig_free(&rig);
		return status;
	}
	*r_rig = rig;
	return 0;
}
