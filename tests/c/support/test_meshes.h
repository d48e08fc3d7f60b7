/*
 * test_meshes.h - real test geometry for the C tests and the benchmark: the paper's cylinder,
 * a three-phalanx finger, long bone chains, the giraffe loaded from tests/data/giraffe, forward
 * kinematics to pose them, and an exact triangle-triangle intersection count.
 * Loaders and builders live here, in the tests, never in csrc/.
 */
#ifndef LVP_TEST_MESHES_H
#define LVP_TEST_MESHES_H

#include "lvp.h"

#include <stdint.h>

/* A skinned mesh with its skeleton, all arrays malloc'ed (free with test_rig_free).
 * Bone frames follow Blender's convention: origin at the head, local +Y along the bone. */
typedef struct test_rig {
	int32_t vertex_count, triangle_count, bone_count;
	float *positions;        /* vertex_count*3, rest */
	int32_t *triangles;      /* triangle_count*3, counter-clockwise seen from outside */
	int32_t *weight_offsets; /* vertex_count+1 (CSR) */
	int32_t *weight_bones;
	float *weight_values;
	float *rest_matrices; /* bone_count*16, row-major (see lvp.h) */
	float *heads, *tails; /* bone_count*3 */
	int32_t *parents;     /* bone_count, -1 for a root */
	char (*names)[48];    /* bone_count names, or NULL */
} test_rig;

void test_rig_free(test_rig *rig);
lvp_weights test_rig_weights(const test_rig *rig);
lvp_skeleton test_rig_skeleton(const test_rig *rig);
int32_t test_find_bone(const test_rig *rig, const char *name); /* -1 when absent */

/* The paper's cylinder along +Z from z = 0 to z = length: `around` x `along` side vertices
 * (rings equally spaced, the first at z = 0, the last at z = length), closed by one centre
 * vertex per cap (appended last). Two bones: 0 from z = 0 to length/2, 1 from length/2 to
 * length (parent 0). Weights blend linearly over a band of width `band` centred on the joint:
 * w1 = clamp((z - (length - band)/2) / band, 0, 1), w0 = 1 - w1; zero weights are not stored.
 * test_make_cylinder(16, 16, 0.5f, 4.0f, 2.6f) is the paper's. */
test_rig test_make_cylinder(int around, int along, float radius, float length, float band);
/* test_make_cylinder, with every odd ring but the last given a twin `gap` of the ring spacing above it
 * (0 < gap < 1): a strip of needle triangles around it, whose short edges are what marching cubes
 * (metaballs, voxel tools) leave where the surface passes near a corner of their grid. */
test_rig test_make_cylinder_twinned(int around, int along, float radius, float length, float band, float gap);

/* A chain of `bone_count` equal bones along +Z, each `bone_length` long, skinned as a tube of
 * `around` x `rings_per_bone*bone_count + 1` vertices with caps; weights blend linearly over
 * `band` (a fraction of a bone length, in (0, 1]) around every joint. For benchmarks. */
test_rig test_make_chain(int bone_count, float bone_length, float radius, int around, int rings_per_bone,
                         float band);

/* A finger: a closed tube with a rounded tip along +Y, three phalanges (bones 0, 1, 2, lengths
 * 1.0, 0.7, 0.5, radius about 0.22), weights blending over short bands at the two knuckles so
 * that bending them far makes plain skinning cross itself on the inside of the bend.
 * Measured (test_support.c): 16 x 40 tube + 4 tip rings + 2 poles = 706 vertices, bands of 0.2
 * centred on the knuckles (y = 1.0 and 1.7). Bone frames are the world axes moved to the head,
 * so the bend is a rotation about local X (+X turns the tip towards +Z). At rest: no
 * intersecting pair. Plain skinning crosses itself from about 50 degrees per knuckle on; the
 * reference bend is 100 degrees at both knuckles (bones 1 and 2, axis (1, 0, 0)): 124
 * intersecting pairs, all at the knuckles (the sum of each knuckle bent alone). Up to 110
 * degrees that stays so; from 115 degrees the fingertip also reaches the first phalanx, a
 * contact between non-neighbouring bones that fold-over prevention is not meant to fix. */
test_rig test_make_finger(void);

/* Rebuilds the weights of a test_make_finger() rig with its blend bands centred `shift` short of
 * each knuckle, towards the base (as heat weights put them where a finger meets the palm). */
void test_shift_finger_bands(test_rig *rig, double shift);

/* The giraffe of tests/data/giraffe (the paper's model): 1673 vertices, triangulated by fans,
 * winding flipped to face outward. Bone j runs from joint j to its child (see support/giraffe_loader.c for
 * the rule with several children or none). Returns 0 on success.
 * Unlike the built rigs, rest_matrices are the joints' world frames from the file, whose local
 * X (not Y) runs along the bone: test_pose() axes for the giraffe are in those frames. */
int test_load_giraffe(test_rig *r_rig, const char *directory);

/* Forward kinematics. local_rotations: bone_count*4 (axis x, y, z in the bone's rest frame,
 * angle in radians; a zero axis or angle = no rotation); each bone turns about its head and
 * carries its children. r_posed: bone_count*16 posed bone frames T_i (row-major). */
void test_pose(float *r_posed, const test_rig *rig, const float *local_rotations);

/* r_skin[i] = posed_i * rest_i^-1 (bone_count*16), what lvp_skin_linear() takes. */
void test_skin_matrices(float *r_skin, const test_rig *rig, const float *posed);

/* Poses the rig by local_rotations (test_pose) and skins it by linear blend: *r_posed receives the
 * bone matrices (bone_count*16), *r_skinned the positions (vertex_count*3), both malloc'ed. Returns
 * 0, or -1 when the core refuses the skinning. */
int test_pose_and_skin(const test_rig *rig, const float *local_rotations, float **r_posed, float **r_skinned);

/* A rig with its pose: the bone matrices (bone_count*16) and the positions skinned by them
 * (vertex_count*3), all owned (test_posed_rig_free). */
typedef struct test_posed_rig {
	test_rig rig;
	float *posed, *skinned;
} test_posed_rig;

/* Takes `rig` and poses it by local_rotations (test_pose_and_skin) into *r. Returns 0, or -1 when
 * the core refuses the skinning (*r is then still to be freed). */
int test_pose_rig(test_rig rig, const float *local_rotations, test_posed_rig *r);
void test_posed_rig_free(test_posed_rig *p);

/* r = a * b, 4x4 row-major (r may be a or b). */
void test_multiply_matrices(float r[16], const float a[16], const float b[16]);
/* The same in double precision. */
void test_multiply_matrices_double(double r[16], const double a[16], const double b[16]);

/* A posed bone frame (16 floats, row-major) times a scale in its own frame: the bone scaled by
 * sx, sy, sz along its axes (Y along the bone) about its head, as Blender scales a pose bone. */
void test_scale_bone(float posed_bone[16], double sx, double sy, double sz);

/* The largest distance between a and b (3 floats per point, count points), or the largest length of a when b
 * is NULL. */
double test_largest_distance(const float *a, const float *b, int32_t count);

/* The roughness of offsets (3 per vertex) as ../shared/QUALITY.md measures it: the largest
 * |offset - the mean of its edge neighbours' offsets|, over the largest offset (0 when none). */
double test_roughness(const test_rig *rig, const float *offsets);

/* Number of pairs of triangles that intersect, decided exactly (rational arithmetic on the
 * float coordinates). Pairs that share a vertex or an edge count only when they meet
 * somewhere other than their shared vertex or edge. Zero-area triangles are ignored. */
int64_t test_count_intersecting_pairs(const float *positions, const int32_t *triangles, int32_t triangle_count);

/* Splits every triangle in four at its edge midpoints, `levels` times (the surface keeps its
 * shape and volume); a midpoint's weights are the average of its edge's. For benchmarks. */
test_rig test_subdivide(const test_rig *rig, int levels);

/* Reads a whole file into a malloc'ed, NUL-terminated buffer; NULL on failure. */
/* rig split into islands as a glTF round trip splits a mesh at its UV seams: triangles are
 * grouped by the quadrant of their centroid around the z axis, and a vertex used by several
 * groups gets a copy for each group after its first (appended, with its weights). r_original
 * (malloc'ed): the vertex each vertex of the split mesh copies. */
test_rig test_split_at_seams(const test_rig *rig, int32_t **r_original);

char *test_read_file(const char *path, size_t *r_size);

#endif
