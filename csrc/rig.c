/*
 * rig.c - the rig as the core keeps it: the skinning weights, normalized by their sum, and the
 * bones' rest frames, copied at bind; each frame, the posed bones and what follows from them
 * (skin matrices, the volume ratio kappa of each region's bone, the bones scaled to zero).
 */
#include "binding.h"

#include <stdlib.h>

/* Copies the weights, normalized by their sum (as Blender's Armature modifier normalizes); the
 * bones are already in weight_bones (lvp__split_parts). */
static void lvp__copy_weights(lvp_binding *binding, const lvp_weights *weights)
{
	int32_t n = binding->vertex_count;
	memcpy(binding->rig.weight_offsets, weights->offsets, sizeof(int32_t) * (size_t)(n + 1));
	for (int32_t k = 0; k < n; ++k) {
		int32_t begin = weights->offsets[k], end = weights->offsets[k + 1];
		double sum = 0.0;
		for (int32_t e = begin; e < end; ++e)
			sum += weights->values[e];
		for (int32_t e = begin; e < end; ++e)
			binding->rig.weight_values[e] = sum > 0.0 ? (float)(weights->values[e] / sum) : 0.0f;
	}
}

/* The internal bones: each a copy of its caller's bone (binding.h). */
static void lvp__copy_skeleton(lvp_binding *binding, const lvp_skeleton *skeleton)
{
	binding->rig.reach = 0.0;
	for (int32_t i = 0; i < binding->bone_count; ++i) {
		int32_t source = lvp__caller_bone(binding, i);
		binding->rig.rest_matrices[i] = lvp__mat4_load(skeleton->rest_matrices + 16 * source);
		lvp__mat4_invert_affine(&binding->rig.rest_inverse[i], &binding->rig.rest_matrices[i]); /* checked before */
		binding->rig.rest_det[i] = lvp__mat4_det3(&binding->rig.rest_matrices[i]);
		binding->rig.heads[i] = lvp__load(skeleton->heads + 3 * source);
		binding->rig.tails[i] = lvp__load(skeleton->tails + 3 * source);
		binding->rig.reach = fmax(binding->rig.reach, lvp__length(binding->rig.heads[i]));
	}
}

void lvp__rig_copy(lvp_binding *binding, const lvp_weights *weights, const lvp_skeleton *skeleton)
{
	lvp__copy_weights(binding, weights);
	lvp__copy_skeleton(binding, skeleton);
}

lvp_result lvp__prepare_frame(lvp_binding *binding, const float *bone_matrices, lvp_diagnostic *r_diag)
{
	int32_t b = binding->caller_bone_count;
	lvp_result result;
	bool need_bones = binding->mode == LVP_MODE_LOCAL;
	if (need_bones && !bone_matrices)
		return lvp__fail(r_diag, lvp_error_null_argument, "bone_matrices", -1,
		                 "bone_matrices is NULL; pass the %d posed bone matrices (16 floats each).", (int)b);
	if (bone_matrices && b > 0 &&
	    (result = lvp__check_float_array(bone_matrices, (int64_t)b * 16, "bone_matrices", r_diag)))
		return result;

	for (int32_t r = 0; r < binding->region_count; ++r) {
		if (binding->rig.region_skipped[r])
			lvp__dynamic_set_stale(binding); /* the dynamic set depends on it */
		binding->rig.region_skipped[r] = 0;
		binding->rig.kappa[r] = 1.0;
	}
	if (bone_matrices && b > 0) {
		/* The internal bones past the caller's are copies (binding.h): the same matrices. */
		for (int32_t i = 0; i < binding->bone_count; ++i) {
			int32_t source = lvp__caller_bone(binding, i);
			binding->rig.posed[i] = lvp__mat4_load(bone_matrices + 16 * source);
			binding->rig.skin[i] = lvp__mat4_mul(&binding->rig.posed[i], &binding->rig.rest_inverse[i]);
			binding->rig.posed_heads[i] = lvp__transform_point(&binding->rig.skin[i], binding->rig.heads[i]);
			bool invertible = lvp__mat4_invert_affine(&binding->rig.posed_inverse[i], &binding->rig.posed[i]);
			if (binding->mode != LVP_MODE_LOCAL)
				continue;
			if (invertible) {
				binding->rig.kappa[i] = binding->rig.rest_det[i] / lvp__mat4_det3(&binding->rig.posed[i]);
			} else { /* a bone scaled to zero: the documented fallback */
				binding->rig.region_skipped[i] = 1;
				lvp__dynamic_set_stale(binding);
			}
		}
	}
	return lvp_success;
}

bool lvp__rig_alloc(lvp_binding *binding, const lvp_weights *weights)
{
	size_t n = (size_t)binding->vertex_count, b = (size_t)binding->bone_count, s = (size_t)binding->region_count;
	lvp__rig *rig = &binding->rig;
	bool ok = true;
	if (weights) {
		rig->weight_offsets = lvp__calloc(n + 1, sizeof(int32_t), &ok);
		rig->weight_values = lvp__calloc((size_t)weights->offsets[n], sizeof(float), &ok);
		rig->rest_matrices = lvp__calloc(b, sizeof(lvp__mat4), &ok);
		rig->rest_inverse = lvp__calloc(b, sizeof(lvp__mat4), &ok);
		rig->rest_det = lvp__calloc(b, sizeof(double), &ok);
		rig->heads = lvp__calloc(b, sizeof(lvp__vec3), &ok);
		rig->tails = lvp__calloc(b, sizeof(lvp__vec3), &ok);
		rig->posed = lvp__calloc(b, sizeof(lvp__mat4), &ok);
		rig->posed_inverse = lvp__calloc(b, sizeof(lvp__mat4), &ok);
		rig->skin = lvp__calloc(b, sizeof(lvp__mat4), &ok);
		rig->posed_heads = lvp__calloc(b, sizeof(lvp__vec3), &ok);
	}
	rig->kappa = lvp__calloc(s, sizeof(double), &ok);
	rig->region_skipped = lvp__calloc(s, sizeof(uint8_t), &ok);
	return ok;
}

void lvp__rig_free(lvp__rig *rig)
{
	void *arrays[] = {rig->weight_offsets, rig->weight_bones, rig->weight_values, rig->bone_source,
	                  rig->rest_matrices, rig->rest_inverse, rig->rest_det, rig->heads, rig->tails,
	                  rig->posed, rig->posed_inverse, rig->skin, rig->posed_heads, rig->kappa,
	                  rig->region_skipped};
	for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); ++i)
		free(arrays[i]);
}
