/*
 * lvp_python.c - the CPython extension module _lvp over the C core; its contract is docs/python_module.md.
 *
 * Built against the stable ABI (Py_LIMITED_API 0x030B0000) so that one _lvp.abi3.so loads in every Blender
 * on Python 3.11 and later. Arrays come in through the buffer protocol, so array.array, memoryview and numpy
 * arrays all work and numpy is never imported. Every size is checked here, before the core reads a byte,
 * because the core trusts its counts; everything else (indices, NaN, signs, options) is checked by the core.
 * Every bad argument raises _lvp.Error, a ValueError that names the argument (.argument) and says what is
 * wrong for code to branch on (.code: the core's result, or this module's for a buffer it cannot take); a
 * core diagnostic is passed on with the core's parameter names turned into this module's.
 * Computing calls release the GIL while holding the buffer views, which keeps the exporters from resizing
 * or freeing the memory underneath.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include "lvp.h"

#include <float.h>
#include <math.h>
#include <stdarg.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#define LVP_PY__STRINGIFY(x) #x
#define LVP_PY__VERSION_STRING(major, minor, patch)                                                                 \
	LVP_PY__STRINGIFY(major) "." LVP_PY__STRINGIFY(minor) "." LVP_PY__STRINGIFY(patch)

/* The most buffers one call takes (Binding: mesh, weights, skeleton, parents and map arrays). */
#define LVP_PY__MAX_BUFFERS 13

/* ---- buffers ------------------------------------------------------------------------------------------- */

typedef enum lvp_py__kind { LVP_PY__FLOAT32, LVP_PY__INT32, LVP_PY__FLOAT64 } lvp_py__kind;

static const char *const lvp_py__kind_names[] = {"float32", "int32", "float64"};
static const char *const lvp_py__kind_examples[] = {"array('f')", "array('i')", "array('d')"};

/* One argument's view of the caller's memory. `given` is false when an optional argument is None; data can
 * be NULL for an empty buffer too, so it does not tell the two apart. */
typedef struct lvp_py__array {
	bool given;
	void *data;
	Py_ssize_t count; /* items */
	Py_ssize_t bytes;
	const char *name;
	lvp_py__kind kind;
} lvp_py__array;

/* A core parameter name and the Python argument it comes from. */
typedef struct lvp_py__rename {
	const char *core;
	const char *python;
} lvp_py__rename;

/* What the module keeps per interpreter: its exception type. */
typedef struct lvp_py__state {
	PyObject *error; /* _lvp.Error */
} lvp_py__state;

/* One call: the arguments' buffer views, all released together when the call ends, and how its errors are
 * raised. */
typedef struct lvp_py__call {
	Py_buffer views[LVP_PY__MAX_BUFFERS];
	int count;
	PyObject *error;                     /* _lvp.Error of the module called (borrowed) */
	const lvp_py__rename *renames;       /* this call's core parameter names -> Python names, or NULL */
	lvp_diagnostic diag;                 /* the core's, when it fails */
} lvp_py__call;

/* Starts a call into `module` (NULL when the module is gone, which raises). */
static int lvp_py__begin(lvp_py__call *call, PyObject *module, const lvp_py__rename *renames)
{
	memset(call, 0, sizeof(*call));
	call->renames = renames;
	lvp_py__state *state = module ? PyModule_GetState(module) : NULL;
	if (!state || !state->error) {
		if (!PyErr_Occurred())
			PyErr_SetString(PyExc_SystemError, "_lvp: the module's state is gone");
		return -1;
	}
	call->error = state->error;
	return 0;
}

/* Starts a call of a method of `type` (Binding), which knows its module. */
static int lvp_py__begin_method(lvp_py__call *call, PyTypeObject *type, const lvp_py__rename *renames)
{
	return lvp_py__begin(call, PyType_GetModule(type), renames);
}

static void lvp_py__release(lvp_py__call *call)
{
	while (call->count > 0)
		PyBuffer_Release(&call->views[--call->count]);
}

/* Ends a call whose arguments could not be taken (the error is set): NULL, for the caller to return. */
static PyObject *lvp_py__abandon(lvp_py__call *call)
{
	lvp_py__release(call);
	return NULL;
}

/* Makes an exception of `type` with the message `text` and sets it, with .code and .argument (NULL: None). */
static void lvp_py__set_error(PyObject *type, PyObject *text, const char *code, const char *argument)
{
	PyObject *exception = text ? PyObject_CallFunctionObjArgs(type, text, NULL) : NULL;
	if (!exception)
		return; /* the failure to make it is the error set */
	PyObject *code_object = PyUnicode_FromString(code);
	PyObject *argument_object = argument ? PyUnicode_FromString(argument) : (Py_INCREF(Py_None), Py_None);
	if (code_object && argument_object && PyObject_SetAttrString(exception, "code", code_object) == 0 &&
	    PyObject_SetAttrString(exception, "argument", argument_object) == 0)
		PyErr_SetObject(type, exception);
	Py_XDECREF(code_object);
	Py_XDECREF(argument_object);
	Py_DECREF(exception);
}

/* Codes of the arguments this module refuses before the core sees them; the others are the core's. */
#define LVP_PY__INVALID_BUFFER "invalid_buffer" /* not a buffer of the kind asked, or sharing memory */
#define LVP_PY__INVALID_SIZE "invalid_size"
#define LVP_PY__NULL_ARGUMENT "null_argument"
#define LVP_PY__INVALID_OPTION "invalid_option"

/* Raises _lvp.Error "<message>" about `argument`; the message starts with the argument's name. Returns -1. */
static int lvp_py__argument_error(const lvp_py__call *call, const char *code, const char *argument, const char *format,
                                  ...)
{
	va_list arguments;
	va_start(arguments, format);
	PyObject *text = PyUnicode_FromFormatV(format, arguments);
	va_end(arguments);
	lvp_py__set_error(call->error, text, code, argument);
	Py_XDECREF(text);
	return -1;
}

static char lvp_py__native_order(void)
{
	const uint16_t probe = 1;
	return *(const unsigned char *)&probe == 1 ? '<' : '>';
}

/* True when a struct-module format string describes exactly the item kind the core reads. The item size is
 * checked beside the letter because 'l' is 4 bytes in standard sizes ('=l') but 8 in native ones on 64-bit
 * Linux, and numpy reports int32 as 'i' or 'l' depending on the platform. */
static bool lvp_py__format_matches(const char *format, Py_ssize_t itemsize, lvp_py__kind kind)
{
	if (!format)
		format = "B";
	if (format[0] == '@' || format[0] == '=' || format[0] == lvp_py__native_order())
		format++;
	else if (format[0] == '<' || format[0] == '>' || format[0] == '!')
		return false; /* the other byte order: the core would read garbage */
	if (format[0] == '\0' || format[1] != '\0')
		return false;
	switch (kind) {
	case LVP_PY__FLOAT32:
		return format[0] == 'f' && itemsize == 4;
	case LVP_PY__INT32:
		return (format[0] == 'i' || format[0] == 'l') && itemsize == 4;
	case LVP_PY__FLOAT64:
		return format[0] == 'd' && itemsize == 8;
	}
	return false;
}

/* Raises "<name> must be a C-contiguous <kind> buffer ...; got <what>". */
static int lvp_py__wrong_buffer(const lvp_py__call *call, PyObject *object, const char *name, lvp_py__kind kind,
                                bool writable, const char *problem)
{
	PyObject *type_name = PyType_GetName(Py_TYPE(object));
	if (!type_name)
		return -1;
	lvp_py__argument_error(call, object == Py_None ? LVP_PY__NULL_ARGUMENT : LVP_PY__INVALID_BUFFER, name,
	                       "%s must be a C-contiguous%s %s buffer such as %s; got %U (%s).", name,
	                       writable ? " writable" : "", lvp_py__kind_names[kind], lvp_py__kind_examples[kind],
	                       type_name, problem);
	Py_DECREF(type_name);
	return -1;
}

/* Takes a view of `object` for the argument `name` into the call, checking that it is a C-contiguous,
 * aligned buffer of exactly `kind` items (and writable for outputs). `optional` lets None (or a missing
 * keyword, NULL) through as not given. Sizes are checked by the caller, which knows them. */
static int lvp_py__take(lvp_py__call *call, lvp_py__array *r_array, PyObject *object, const char *name,
                        lvp_py__kind kind, bool writable, bool optional)
{
	memset(r_array, 0, sizeof(*r_array));
	r_array->name = name;
	r_array->kind = kind;
	if (optional && (!object || object == Py_None))
		return 0;
	if (!object || object == Py_None)
		return lvp_py__wrong_buffer(call, Py_None, name, kind, writable, "required");
	if (!PyObject_CheckBuffer(object))
		return lvp_py__wrong_buffer(call, object, name, kind, writable, "no buffer protocol");
	if (call->count >= LVP_PY__MAX_BUFFERS) {
		PyErr_SetString(PyExc_SystemError, "_lvp: too many buffers in one call");
		return -1;
	}
	Py_buffer *view = &call->views[call->count];
	/* Strides and format, read-only: then contiguity and writability are checked below with a message that
	 * says what is wrong, instead of the exporter's generic BufferError. */
	if (PyObject_GetBuffer(object, view, PyBUF_RECORDS_RO) != 0) {
		PyObject *type, *value, *traceback;
		PyErr_Fetch(&type, &value, &traceback);
		lvp_py__argument_error(call, LVP_PY__INVALID_BUFFER, name, "%s could not be read as a buffer (%S).", name,
		                       value ? value : Py_None);
		Py_XDECREF(type);
		Py_XDECREF(value);
		Py_XDECREF(traceback);
		return -1;
	}
	call->count++;
	char problem[96];
	if (!lvp_py__format_matches(view->format, view->itemsize, kind)) {
		snprintf(problem, sizeof(problem), "item format '%.16s', itemsize %zd", view->format ? view->format : "B",
		         view->itemsize);
		return lvp_py__wrong_buffer(call, object, name, kind, writable, problem);
	}
	if (!PyBuffer_IsContiguous(view, 'C'))
		return lvp_py__wrong_buffer(call, object, name, kind, writable, "not C-contiguous; pass a contiguous copy");
	if (writable && view->readonly)
		return lvp_py__wrong_buffer(call, object, name, kind, writable, "read-only");
	/* A memoryview cast from an odd byte offset can be misaligned; the core reads whole floats. */
	if (view->len > 0 && (uintptr_t)view->buf % (uintptr_t)view->itemsize != 0)
		return lvp_py__wrong_buffer(call, object, name, kind, writable, "not aligned to its item size");
	r_array->given = true;
	r_array->data = view->buf;
	r_array->count = view->len / view->itemsize;
	r_array->bytes = view->len;
	return 0;
}

/* Checks that an array holds exactly `expected` items; `why` says where the number comes from. */
static int lvp_py__expect_count(const lvp_py__call *call, const lvp_py__array *array, Py_ssize_t expected,
                                const char *why)
{
	if (!array->given || array->count == expected)
		return 0;
	return lvp_py__argument_error(call, LVP_PY__INVALID_SIZE, array->name, "%s has %zd %s values; expected %zd (%s).",
	                              array->name, array->count, lvp_py__kind_names[array->kind], expected, why);
}

/* Checks that an array holds a positive multiple of `group` items, at most `limit` groups, and returns the
 * number of groups (vertices, triangles, bones). The limit keeps the counts inside the core's int32. */
static int lvp_py__expect_groups(const lvp_py__call *call, const lvp_py__array *array, Py_ssize_t group,
                                 Py_ssize_t limit, const char *what, int32_t *r_groups)
{
	if (array->count == 0 || array->count % group != 0)
		return lvp_py__argument_error(call, LVP_PY__INVALID_SIZE, array->name,
		                              "%s has %zd %s values; expected %zd per %s, a positive multiple of %zd.",
		                              array->name, array->count, lvp_py__kind_names[array->kind], group, what, group);
	if (array->count / group > limit)
		return lvp_py__argument_error(call, LVP_PY__INVALID_SIZE, array->name,
		                              "%s has %zd %ss; at most %zd are supported.", array->name, array->count / group,
		                              what, limit);
	*r_groups = (int32_t)(array->count / group);
	return 0;
}

static bool lvp_py__overlap(const lvp_py__array *a, const lvp_py__array *b)
{
	if (!a->data || !b->data || a->bytes == 0 || b->bytes == 0)
		return false;
	uintptr_t a_begin = (uintptr_t)a->data, b_begin = (uintptr_t)b->data;
	return a_begin < b_begin + (uintptr_t)b->bytes && b_begin < a_begin + (uintptr_t)a->bytes;
}

/* The core reads its inputs while it writes its outputs: an output sharing memory with an input would
 * corrupt the result without any error. */
static int lvp_py__expect_apart(const lvp_py__call *call, const lvp_py__array *output, const lvp_py__array *input)
{
	if (!lvp_py__overlap(output, input))
		return 0;
	return lvp_py__argument_error(call, LVP_PY__INVALID_BUFFER, output->name,
	                              "%s shares memory with %s; pass a separate buffer.", output->name, input->name);
}

/* The CSR weights: offsets has vertex_count+1 entries and its last one is the length of bones and values,
 * which the core would otherwise read past. */
static int lvp_py__expect_weights(const lvp_py__call *call, const lvp_py__array *offsets, const lvp_py__array *bones,
                                  const lvp_py__array *values, int32_t vertex_count)
{
	if (lvp_py__expect_count(call, offsets, (Py_ssize_t)vertex_count + 1, "one per vertex, plus one") != 0)
		return -1;
	int32_t total = ((const int32_t *)offsets->data)[vertex_count];
	const lvp_py__array *influences[2] = {bones, values};
	for (int i = 0; i < 2; ++i)
		if (influences[i]->count != total)
			return lvp_py__argument_error(
			    call, LVP_PY__INVALID_SIZE, influences[i]->name,
			    "%s has %zd %s values; expected %d, the number of influences that %s[%d] (its last entry) announces.",
			    influences[i]->name, influences[i]->count, lvp_py__kind_names[influences[i]->kind], (int)total,
			    offsets->name, (int)vertex_count);
	return 0;
}

/* ---- scalar arguments ---------------------------------------------------------------------------------- */

/* Scalars raise _lvp.Error naming the argument too, so the add-on can report any bad input the same way. */
static int lvp_py__wrong_scalar(const lvp_py__call *call, PyObject *object, const char *name, const char *expected)
{
	PyObject *type_name = PyType_GetName(Py_TYPE(object));
	if (!type_name)
		return -1;
	lvp_py__argument_error(call, LVP_PY__INVALID_OPTION, name, "%s must be %s; got %U.", name, expected, type_name);
	Py_DECREF(type_name);
	return -1;
}

/* NULL (keyword not given) keeps the default already in *r_value. */
static int lvp_py__parse_float(const lvp_py__call *call, PyObject *object, const char *name, float *r_value)
{
	if (!object)
		return 0;
	double value = PyFloat_AsDouble(object);
	if (value == -1.0 && PyErr_Occurred()) {
		PyErr_Clear();
		return lvp_py__wrong_scalar(call, object, name, "a number");
	}
	if (isfinite(value) && fabs(value) > FLT_MAX) {
		return lvp_py__argument_error(call, LVP_PY__INVALID_OPTION, name, "%s is %R, outside the float32 range.", name,
		                              object);
	}
	*r_value = (float)value;
	return 0;
}

static int lvp_py__parse_int(const lvp_py__call *call, PyObject *object, const char *name, int32_t *r_value)
{
	if (!object)
		return 0;
	PyObject *index = PyNumber_Index(object);
	if (!index) {
		PyErr_Clear();
		return lvp_py__wrong_scalar(call, object, name, "an int");
	}
	int overflow = 0;
	long value = PyLong_AsLongAndOverflow(index, &overflow);
	Py_DECREF(index);
	if (value == -1 && PyErr_Occurred())
		return -1;
	if (overflow || value < INT32_MIN || value > INT32_MAX) {
		return lvp_py__argument_error(call, LVP_PY__INVALID_OPTION, name, "%s is %R, outside the int32 range.", name,
		                              object);
	}
	*r_value = (int32_t)value;
	return 0;
}

static int lvp_py__parse_bool(const lvp_py__call *call, PyObject *object, const char *name, int32_t *r_value)
{
	if (!object)
		return 0;
	int truth = PyObject_IsTrue(object);
	if (truth < 0) {
		PyErr_Clear();
		return lvp_py__wrong_scalar(call, object, name, "a bool");
	}
	*r_value = truth;
	return 0;
}

/* Enum arguments are Blender-style identifiers ('LOCAL', 'ORGANIC'); their index is the C enum value. */
static int lvp_py__parse_choice(const lvp_py__call *call, PyObject *object, const char *name,
                                const char *const *choices, int choice_count, int *r_index)
{
	if (!object)
		return 0;
	if (PyUnicode_Check(object)) {
		for (int i = 0; i < choice_count; ++i)
			if (PyUnicode_CompareWithASCIIString(object, choices[i]) == 0) {
				*r_index = i;
				return 0;
			}
	}
	char list[160] = "";
	for (int i = 0; i < choice_count; ++i) {
		size_t used = strlen(list);
		snprintf(list + used, sizeof(list) - used, "%s'%s'", i ? ", " : "", choices[i]);
	}
	return lvp_py__argument_error(call, LVP_PY__INVALID_OPTION, name, "%s must be one of %s; got %R.", name, list,
	                              object);
}

static const char *const lvp_py__mode_names[] = {"LOCAL", "GLOBAL"};
static const char *const lvp_py__map_names[] = {"ORGANIC", "RUBBER", "BOUNDARY_FADE", "PAINTED", "UNIFORM"};
static const char *const lvp_py__visibility_names[] = {"NORMAL", "EXACT", "NONE"};
static const char *const lvp_py__restore_names[] = {"EACH_REGION", "WHOLE_MESH"};

/* ---- core diagnostics -> Python exceptions ----------------------------------------------------------- */

/* Names that mean the same argument in every call. */
static const lvp_py__rename lvp_py__common_renames[] = {
    {"weights", "weight_offsets"},
    {"weights.offsets", "weight_offsets"},
    {"weights.bones", "weight_bones"},
    {"weights.values", "weight_values"},
    {"skeleton", "rest_matrices"},
    {"skeleton.bone_count", "rest_matrices"},
    {"skeleton.rest_matrices", "rest_matrices"},
    {"skeleton.heads", "heads"},
    {"skeleton.tails", "tails"},
    {"skeleton.parents", "parents"},
    {"triangle_count", "triangles"},
    {"options.thread_count", "threads"},
    {"options.bulge_width", "bulge_width"},
    {"thread_count", "threads"},
    {"options.max_iterations", "iterations"},
    {"max_iterations", "iterations"},
    {"options.map", "map"},
    {"options.map.map", "map"},
    {"map.map", "map"},
    {NULL, NULL},
};

/* Option fields are named like the keywords once their struct prefix is gone ("options.map.alpha" is
 * alpha): this keeps the names right for fields the core adds later. */
static const char *const lvp_py__core_prefixes[] = {"options.map.", "options.", "map.", "skeleton."};

static const char *lvp_py__python_name(const char *core, const lvp_py__rename *call_renames)
{
	if (!core)
		return NULL;
	const lvp_py__rename *tables[2] = {call_renames, lvp_py__common_renames};
	for (int t = 0; t < 2; ++t)
		for (const lvp_py__rename *rename = tables[t]; rename && rename->core; ++rename)
			if (strcmp(core, rename->core) == 0)
				return rename->python;
	for (size_t i = 0; i < sizeof(lvp_py__core_prefixes) / sizeof(lvp_py__core_prefixes[0]); ++i) {
		size_t length = strlen(lvp_py__core_prefixes[i]);
		if (strncmp(core, lvp_py__core_prefixes[i], length) == 0 && core[length] != '\0')
			return core + length;
	}
	return core;
}

static bool lvp_py__identifier_char(char c)
{
	return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') || c == '_';
}

/* C words in the core's sentences and what a Python caller passes instead. */
static const lvp_py__rename lvp_py__words[] = {
    {"NULL", "None"},
    {"LVP_MODE_GLOBAL", "mode='GLOBAL'"},
    {"LVP_MODE_LOCAL", "mode='LOCAL'"},
    {NULL, NULL},
};

/* The length of `word` when the message continues with it as a whole word at c, else 0. */
static size_t lvp_py__word_at(const char *message, const char *c, const char *word)
{
	size_t length = strlen(word);
	bool starts = c == message || (!lvp_py__identifier_char(c[-1]) && c[-1] != '.');
	return starts && strncmp(c, word, length) == 0 && !lvp_py__identifier_char(c[length]) ? length : 0;
}

/* Copies the core's sentence into r_message in Python's words: the Python name wherever the core wrote a
 * dotted struct field ("weights.values[3] is -1" -> "weight_values[3] is -1"), None for NULL. Plain names
 * such as vertex_count are left alone: they stay true as they are and the argument is prefixed instead. */
static void lvp_py__rewrite(char *r_message, size_t capacity, const char *message, const char *core,
                            const char *python)
{
	bool rename = core && python && strcmp(core, python) != 0 && strchr(core, '.') != NULL;
	size_t used = 0;
	for (const char *c = message; *c && used + 1 < capacity;) {
		const char *replacement = NULL;
		size_t length = 0;
		if (rename && (length = lvp_py__word_at(message, c, core)) != 0)
			replacement = python;
		for (const lvp_py__rename *word = lvp_py__words; !replacement && word->core; ++word)
			if ((length = lvp_py__word_at(message, c, word->core)) != 0)
				replacement = word->python;
		if (replacement) {
			for (const char *p = replacement; *p && used + 1 < capacity; ++p)
				r_message[used++] = *p;
			c += length;
		} else {
			r_message[used++] = *c++;
		}
	}
	r_message[used] = '\0';
}

/* Raises the exception for a failed core call: MemoryError when memory ran out, RuntimeError when worker
 * threads could not start (nothing the caller passed is wrong), _lvp.Error otherwise, whose message starts
 * with the Python argument's name. Each carries .code, the core's result without its prefix
 * ("mesh_not_closed"), and .argument, the Python name of the argument at fault or None. */
static void lvp_py__raise(const lvp_py__call *call, lvp_result result)
{
	const lvp_diagnostic *diag = &call->diag;
	PyObject *type = result == lvp_error_out_of_memory ? PyExc_MemoryError
	                 : result == lvp_error_thread      ? PyExc_RuntimeError
	                                                   : call->error;
	const char *name = lvp_py__python_name(diag->argument, call->renames);
	char message[sizeof(diag->message) + 128];
	lvp_py__rewrite(message, sizeof(message), diag->message[0] ? diag->message : lvp_result_name(result),
	                diag->argument, name);
	size_t name_length = name ? strlen(name) : 0;
	bool starts_with_name =
	    name && strncmp(message, name, name_length) == 0 && !lvp_py__identifier_char(message[name_length]);
	PyObject *text = type == call->error && name && !starts_with_name ? PyUnicode_FromFormat("%s: %s", name, message)
	                                                                  : PyUnicode_FromString(message);
	const char *code = lvp_result_name(result);
	const char *prefix = "lvp_error_";
	if (strncmp(code, prefix, strlen(prefix)) == 0)
		code += strlen(prefix);
	lvp_py__set_error(type, text, code, name);
	Py_XDECREF(text);
}

/* Ends a call: releases its views and raises when the core's result is a failure. Returns 0 on success. */
static int lvp_py__end(lvp_py__call *call, lvp_result result)
{
	lvp_py__release(call);
	if (result == lvp_success)
		return 0;
	lvp_py__raise(call, result);
	return -1;
}

/* ---- results as array.array -------------------------------------------------------------------------- */

/* A new array.array of `typecode` holding a copy of `bytes` bytes at `data`. The array module is imported
 * per call (a dictionary lookup once loaded), which keeps it out of the module's state. */
static PyObject *lvp_py__new_array(const char *typecode, const void *data, Py_ssize_t bytes)
{
	PyObject *array_module = PyImport_ImportModule("array");
	if (!array_module)
		return NULL;
	PyObject *array = PyObject_CallMethod(array_module, "array", "s", typecode);
	Py_DECREF(array_module);
	if (!array || bytes == 0)
		return array;
	PyObject *memory = PyMemoryView_FromMemory((char *)data, bytes, PyBUF_READ);
	PyObject *none = memory ? PyObject_CallMethod(array, "frombytes", "O", memory) : NULL;
	Py_XDECREF(memory);
	if (!none) {
		Py_DECREF(array);
		return NULL;
	}
	Py_DECREF(none);
	return array;
}

/* ---- stand-alone functions --------------------------------------------------------------------------- */

/* Checks that the arrays of a unit (the weights, the skeleton) are given all or none; `names` lists them for
 * the message. Returns whether they are given. */
static int lvp_py__expect_together(const lvp_py__call *call, const lvp_py__array *const *parts, int count,
                                   const char *what, const char *names, bool *r_given)
{
	bool any = false;
	for (int i = 0; i < count; ++i)
		any = any || parts[i]->given;
	*r_given = any;
	for (int i = 0; any && i < count; ++i)
		if (!parts[i]->given)
			return lvp_py__argument_error(call, LVP_PY__NULL_ARGUMENT, parts[i]->name,
			                              "%s is None but the other %s arrays are given; pass %s together, or all "
			                              "three as None.",
			                              parts[i]->name, what, names);
	return 0;
}

static const lvp_py__rename lvp_py__mesh_renames[] = {
    {"vertex_count", "positions"}, {"r_gradient", "out"}, {"r_normals", "out"}, {NULL, NULL}};

/* Takes positions and triangles, the two inputs of every mesh function. */
static int lvp_py__take_mesh(lvp_py__call *call, lvp_py__array *r_positions, lvp_py__array *r_triangles,
                             PyObject *positions, PyObject *triangles, const char *positions_name,
                             int32_t *r_vertex_count, int32_t *r_triangle_count)
{
	if (lvp_py__take(call, r_positions, positions, positions_name, LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(call, r_triangles, triangles, "triangles", LVP_PY__INT32, false, false) != 0 ||
	    lvp_py__expect_groups(call, r_positions, 3, LVP_MAX_VERTICES, "vertex", r_vertex_count) != 0 ||
	    lvp_py__expect_groups(call, r_triangles, 3, LVP_MAX_TRIANGLES, "triangle", r_triangle_count) != 0)
		return -1;
	return 0;
}

static PyObject *lvp_py__mesh_volume(PyObject *module, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"positions", "triangles", NULL};
	PyObject *positions_object, *triangles_object;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OO:mesh_volume", keywords, &positions_object, &triangles_object))
		return NULL;
	lvp_py__call call;
	lvp_py__array positions, triangles;
	int32_t vertex_count = 0, triangle_count = 0;
	if (lvp_py__begin(&call, module, lvp_py__mesh_renames) != 0 ||
	    lvp_py__take_mesh(&call, &positions, &triangles, positions_object, triangles_object, "positions", &vertex_count,
	                      &triangle_count) != 0)
		return lvp_py__abandon(&call);
	double volume = 0.0;
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_mesh_volume(&volume, positions.data, vertex_count, triangles.data, triangle_count, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end(&call, result) != 0)
		return NULL;
	return PyFloat_FromDouble(volume);
}

typedef lvp_result (*lvp_py__mesh_field)(float *r_values, const float *positions, int32_t vertex_count,
                                         const int32_t *triangles, int32_t triangle_count, lvp_diagnostic *r_diag);

/* volume_gradient and vertex_normals: out (float32[3N]) from positions and triangles. */
static PyObject *lvp_py__mesh_field_call(PyObject *module, PyObject *args, PyObject *kwargs, const char *format,
                                         lvp_py__mesh_field field)
{
	static char *keywords[] = {"out", "positions", "triangles", NULL};
	PyObject *out_object, *positions_object, *triangles_object;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, format, keywords, &out_object, &positions_object,
	                                 &triangles_object))
		return NULL;
	lvp_py__call call;
	lvp_py__array out, positions, triangles;
	int32_t vertex_count = 0, triangle_count = 0;
	if (lvp_py__begin(&call, module, lvp_py__mesh_renames) != 0 ||
	    lvp_py__take_mesh(&call, &positions, &triangles, positions_object, triangles_object, "positions", &vertex_count,
	                      &triangle_count) != 0 ||
	    lvp_py__take(&call, &out, out_object, "out", LVP_PY__FLOAT32, true, false) != 0 ||
	    lvp_py__expect_count(&call, &out, (Py_ssize_t)vertex_count * 3, "3 per vertex of positions") != 0 ||
	    lvp_py__expect_apart(&call, &out, &positions) != 0 || lvp_py__expect_apart(&call, &out, &triangles) != 0)
		return lvp_py__abandon(&call);
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = field(out.data, positions.data, vertex_count, triangles.data, triangle_count, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end(&call, result) != 0)
		return NULL;
	Py_RETURN_NONE;
}

static PyObject *lvp_py__volume_gradient(PyObject *module, PyObject *args, PyObject *kwargs)
{
	return lvp_py__mesh_field_call(module, args, kwargs, "OOO:volume_gradient", lvp_volume_gradient);
}

static PyObject *lvp_py__vertex_normals(PyObject *module, PyObject *args, PyObject *kwargs)
{
	return lvp_py__mesh_field_call(module, args, kwargs, "OOO:vertex_normals", lvp_vertex_normals);
}

typedef lvp_result (*lvp_py__skinning)(float *r_positions, const float *rest_positions, int32_t vertex_count,
                                       const lvp_weights *weights, const float *skin_matrices, int32_t bone_count,
                                       lvp_diagnostic *r_diag);

static const lvp_py__rename lvp_py__skin_renames[] = {
    {"vertex_count", "rest_positions"}, {"bone_count", "skin_matrices"}, {"r_positions", "out"}, {NULL, NULL}};

/* Checks that out shares no memory with any of the inputs. */
static int lvp_py__expect_apart_from_all(const lvp_py__call *call, const lvp_py__array *out,
                                         const lvp_py__array *const *inputs, size_t input_count)
{
	for (size_t i = 0; i < input_count; ++i)
		if (lvp_py__expect_apart(call, out, inputs[i]) != 0)
			return -1;
	return 0;
}

/* skin_linear and skin_dual_quaternion share their arguments. */
static PyObject *lvp_py__skin_call(PyObject *module, PyObject *args, PyObject *kwargs, const char *format,
                                   lvp_py__skinning skinning)
{
	static char *keywords[] = {"out", "rest_positions", "weight_offsets", "weight_bones", "weight_values",
	                           "skin_matrices", NULL};
	PyObject *objects[6];
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, format, keywords, &objects[0], &objects[1], &objects[2],
	                                 &objects[3], &objects[4], &objects[5]))
		return NULL;
	lvp_py__call call;
	lvp_py__array out, rest, offsets, bones, values, matrices;
	const lvp_py__array *inputs[] = {&rest, &offsets, &bones, &values, &matrices};
	int32_t vertex_count = 0, bone_count = 0;
	if (lvp_py__begin(&call, module, lvp_py__skin_renames) != 0 ||
	    lvp_py__take(&call, &rest, objects[1], "rest_positions", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &offsets, objects[2], "weight_offsets", LVP_PY__INT32, false, false) != 0 ||
	    lvp_py__take(&call, &bones, objects[3], "weight_bones", LVP_PY__INT32, false, false) != 0 ||
	    lvp_py__take(&call, &values, objects[4], "weight_values", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &matrices, objects[5], "skin_matrices", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &out, objects[0], "out", LVP_PY__FLOAT32, true, false) != 0 ||
	    lvp_py__expect_groups(&call, &rest, 3, LVP_MAX_VERTICES, "vertex", &vertex_count) != 0 ||
	    lvp_py__expect_groups(&call, &matrices, 16, LVP_MAX_BONES, "bone", &bone_count) != 0 ||
	    lvp_py__expect_weights(&call, &offsets, &bones, &values, vertex_count) != 0 ||
	    lvp_py__expect_count(&call, &out, (Py_ssize_t)vertex_count * 3, "3 per vertex of rest_positions") != 0 ||
	    lvp_py__expect_apart_from_all(&call, &out, inputs, sizeof(inputs) / sizeof(inputs[0])) != 0)
		return lvp_py__abandon(&call);
	lvp_weights weights = {offsets.data, bones.data, values.data};
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = skinning(out.data, rest.data, vertex_count, &weights, matrices.data, bone_count, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end(&call, result) != 0)
		return NULL;
	Py_RETURN_NONE;
}

static PyObject *lvp_py__skin_linear(PyObject *module, PyObject *args, PyObject *kwargs)
{
	return lvp_py__skin_call(module, args, kwargs, "OOOOOO:skin_linear", lvp_skin_linear);
}

static PyObject *lvp_py__skin_dual_quaternion(PyObject *module, PyObject *args, PyObject *kwargs)
{
	return lvp_py__skin_call(module, args, kwargs, "OOOOOO:skin_dual_quaternion", lvp_skin_dual_quaternion);
}

/* ---- posed frames from Blender's matrices ------------------------------------------------------------- */

/* A 4x4 matrix stored column by column (as Blender keeps it) -> row by row (as the core reads it). */
static void lvp_py__rows_of_columns(float r_rows[16], const float *columns)
{
	for (int row = 0; row < 4; ++row)
		for (int column = 0; column < 4; ++column)
			r_rows[4 * row + column] = columns[4 * column + row];
}

/* r = a @ b, all row by row, computed as Blender's mathutils computes Matrix @ Matrix: each product in
 * float, summed in double from 0 in order, rounded once to float. The frames composed here are then bit for
 * bit the ones the add-on composed in Python before (and a frame's -0.0 stays what mathutils makes of it). */
static void lvp_py__multiply(float r[16], const float a[16], const float b[16])
{
	for (int row = 0; row < 4; ++row)
		for (int column = 0; column < 4; ++column) {
			double dot = 0.0;
			for (int item = 0; item < 4; ++item)
				dot += (double)(a[4 * row + item] * b[4 * item + column]);
			r[4 * row + column] = (float)dot;
		}
}

/* The frames: per bone, premat @ bone, or premat @ bone @ joint for each of its joints, then @ correction
 * when corrections are given; inputs column by column, r_frames row by row. */
static void lvp_py__compose(float *r_frames, const float *premat_columns, const float *bone_columns,
                            const int32_t *joint_counts, int32_t bone_count, const float *joint_columns,
                            const float *correction_columns)
{
	float premat[16], bone[16], joint[16], correction[16], posed_bone[16], frame[16];
	lvp_py__rows_of_columns(premat, premat_columns);
	for (int32_t b = 0; b < bone_count; ++b) {
		lvp_py__rows_of_columns(bone, bone_columns + 16 * (size_t)b);
		lvp_py__multiply(posed_bone, premat, bone);
		int32_t frames = joint_counts[b] == 0 ? 1 : joint_counts[b];
		for (int32_t j = 0; j < frames; ++j) {
			if (joint_counts[b] == 0) {
				memcpy(frame, posed_bone, sizeof(frame));
			} else {
				lvp_py__rows_of_columns(joint, joint_columns);
				joint_columns += 16;
				lvp_py__multiply(frame, posed_bone, joint);
			}
			if (correction_columns) {
				lvp_py__rows_of_columns(correction, correction_columns);
				correction_columns += 16;
				lvp_py__multiply(r_frames, frame, correction);
			} else {
				memcpy(r_frames, frame, sizeof(frame));
			}
			r_frames += 16;
		}
	}
}

static PyObject *lvp_py__compose_frames(PyObject *module, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"out", "premat", "bone_matrices", "joint_counts", "joint_matrices", "corrections",
	                           NULL};
	PyObject *objects[6] = {NULL, NULL, NULL, NULL, NULL, NULL};
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOO|O:compose_frames", keywords, &objects[0], &objects[1],
	                                 &objects[2], &objects[3], &objects[4], &objects[5]))
		return NULL;
	lvp_py__call call;
	lvp_py__array out, premat, bones, counts, joints, corrections;
	const lvp_py__array *inputs[] = {&premat, &bones, &counts, &joints, &corrections};
	int32_t bone_count = 0;
	if (lvp_py__begin(&call, module, NULL) != 0 ||
	    lvp_py__take(&call, &premat, objects[1], "premat", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &bones, objects[2], "bone_matrices", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &counts, objects[3], "joint_counts", LVP_PY__INT32, false, false) != 0 ||
	    lvp_py__take(&call, &joints, objects[4], "joint_matrices", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(&call, &corrections, objects[5], "corrections", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__take(&call, &out, objects[0], "out", LVP_PY__FLOAT32, true, false) != 0 ||
	    lvp_py__expect_count(&call, &premat, 16, "one 4x4 matrix") != 0 ||
	    (bones.count > 0 && lvp_py__expect_groups(&call, &bones, 16, LVP_MAX_BONES, "bone", &bone_count) != 0) ||
	    lvp_py__expect_count(&call, &counts, bone_count, "one per bone of bone_matrices") != 0)
		return lvp_py__abandon(&call);
	/* Frames and joints are counted in 64 bits: the counts come from the caller. */
	const int32_t *joint_counts = counts.data;
	int64_t frame_total = 0, joint_total = 0;
	for (int32_t b = 0; b < bone_count; ++b) {
		if (joint_counts[b] < 0 || joint_counts[b] > LVP_MAX_BONES) {
			lvp_py__argument_error(&call, LVP_PY__INVALID_SIZE, "joint_counts",
			                       "joint_counts[%d] is %d; expected 0 (a whole bone) or its number of joints, at most "
			                       "%d.",
			                       (int)b, (int)joint_counts[b], LVP_MAX_BONES);
			return lvp_py__abandon(&call);
		}
		frame_total += joint_counts[b] == 0 ? 1 : joint_counts[b];
		joint_total += joint_counts[b];
	}
	if (lvp_py__expect_count(&call, &joints, (Py_ssize_t)(16 * joint_total), "16 per joint that joint_counts count") !=
	        0 ||
	    lvp_py__expect_count(&call, &out, (Py_ssize_t)(16 * frame_total),
	                         "16 per frame: one per whole bone and one per joint") != 0 ||
	    lvp_py__expect_count(&call, &corrections, (Py_ssize_t)(16 * frame_total), "16 per frame, as out") != 0 ||
	    lvp_py__expect_apart_from_all(&call, &out, inputs, sizeof(inputs) / sizeof(inputs[0])) != 0)
		return lvp_py__abandon(&call);
	lvp_py__compose(out.data, premat.data, bones.data, joint_counts, bone_count, joints.data,
	                corrections.given ? corrections.data : NULL);
	lvp_py__release(&call);
	Py_RETURN_NONE;
}

/* Takes the skeleton arrays: rest_matrices gives the bone count, heads and tails follow it. All three may
 * be None together when `optional` (a prop without bones), and then r_skeleton is left NULL-filled. */
static int lvp_py__take_skeleton(lvp_py__call *call, lvp_skeleton *r_skeleton, PyObject *matrices_object,
                                 PyObject *heads_object, PyObject *tails_object, bool optional)
{
	lvp_py__array matrices, heads, tails;
	const lvp_py__array *parts[3] = {&matrices, &heads, &tails};
	bool given = false;
	memset(r_skeleton, 0, sizeof(*r_skeleton));
	if (lvp_py__take(call, &matrices, matrices_object, "rest_matrices", LVP_PY__FLOAT32, false, optional) != 0 ||
	    lvp_py__take(call, &heads, heads_object, "heads", LVP_PY__FLOAT32, false, optional) != 0 ||
	    lvp_py__take(call, &tails, tails_object, "tails", LVP_PY__FLOAT32, false, optional) != 0 ||
	    lvp_py__expect_together(call, parts, 3, "skeleton", "rest_matrices, heads and tails", &given) != 0)
		return -1;
	if (!given)
		return 0;
	int32_t bone_count = 0;
	if (lvp_py__expect_groups(call, &matrices, 16, LVP_MAX_BONES, "bone", &bone_count) != 0 ||
	    lvp_py__expect_count(call, &heads, (Py_ssize_t)bone_count * 3, "3 per bone of rest_matrices") != 0 ||
	    lvp_py__expect_count(call, &tails, (Py_ssize_t)bone_count * 3, "3 per bone of rest_matrices") != 0)
		return -1;
	r_skeleton->bone_count = bone_count;
	r_skeleton->rest_matrices = matrices.data;
	r_skeleton->heads = heads.data;
	r_skeleton->tails = tails.data;
	return 0;
}

static const lvp_py__rename lvp_py__auto_weights_renames[] = {{"vertex_count", "positions"},
                                                              {"bone_count", "rest_matrices"},
                                                              {"r_offsets", "positions"},
                                                              {"r_bones", "max_influences"},
                                                              {"r_values", "max_influences"},
                                                              {"capacity", "max_influences"},
                                                              {NULL, NULL}};

static PyObject *lvp_py__auto_weights(PyObject *module, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"positions",      "triangles",      "rest_matrices", "heads",      "tails",
	                           "alpha",          "visibility",     "normal_cos_max", "max_influences", "min_weight",
	                           "smoothing_iterations", "smoothing_length", "by_length", "smoothing_thickness", "facing",
	                           "heat",           "threads",        NULL};
	PyObject *positions_object, *triangles_object, *matrices_object, *heads_object, *tails_object;
	PyObject *alpha = NULL, *visibility = NULL, *normal_cos_max = NULL, *max_influences = NULL, *min_weight = NULL;
	PyObject *smoothing_iterations = NULL, *smoothing_length = NULL, *by_length = NULL, *smoothing_thickness = NULL;
	PyObject *facing = NULL, *heat = NULL, *threads = NULL;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOO|$OOOOOOOOOOOO:auto_weights", keywords, &positions_object,
	                                 &triangles_object, &matrices_object, &heads_object, &tails_object, &alpha,
	                                 &visibility, &normal_cos_max, &max_influences, &min_weight,
	                                 &smoothing_iterations, &smoothing_length, &by_length, &smoothing_thickness, &facing,
	                                 &heat, &threads))
		return NULL;
	lvp_py__call call;
	lvp_auto_weights_options options = lvp_auto_weights_default_options();
	int visibility_index = (int)options.visibility;
	lvp_py__array positions, triangles;
	lvp_skeleton skeleton;
	int32_t vertex_count = 0, triangle_count = 0;
	if (lvp_py__begin(&call, module, lvp_py__auto_weights_renames) != 0 ||
	    lvp_py__parse_float(&call, alpha, "alpha", &options.alpha) != 0 ||
	    lvp_py__parse_choice(&call, visibility, "visibility", lvp_py__visibility_names, 3, &visibility_index) != 0 ||
	    lvp_py__parse_float(&call, normal_cos_max, "normal_cos_max", &options.normal_cos_max) != 0 ||
	    lvp_py__parse_int(&call, max_influences, "max_influences", &options.max_influences) != 0 ||
	    lvp_py__parse_float(&call, min_weight, "min_weight", &options.min_weight) != 0 ||
	    lvp_py__parse_int(&call, smoothing_iterations, "smoothing_iterations", &options.smoothing_iterations) != 0 ||
	    lvp_py__parse_float(&call, smoothing_length, "smoothing_length", &options.smoothing_length) != 0 ||
	    lvp_py__parse_float(&call, smoothing_thickness, "smoothing_thickness", &options.smoothing_thickness) != 0 ||
	    lvp_py__parse_bool(&call, by_length, "by_length", &options.by_length) != 0 ||
	    lvp_py__parse_bool(&call, facing, "facing", &options.facing) != 0 ||
	    lvp_py__parse_bool(&call, heat, "heat", &options.heat) != 0 ||
	    lvp_py__parse_int(&call, threads, "threads", &options.thread_count) != 0 ||
	    lvp_py__take_mesh(&call, &positions, &triangles, positions_object, triangles_object, "positions", &vertex_count,
	                      &triangle_count) != 0 ||
	    lvp_py__take_skeleton(&call, &skeleton, matrices_object, heads_object, tails_object, false) != 0)
		return lvp_py__abandon(&call);
	options.visibility = (lvp_visibility)visibility_index;
	/* A negative bound means the options are invalid: the core says which one, given room for nothing. */
	int64_t capacity = lvp_auto_weights_bound(vertex_count, skeleton.bone_count, &options);
	if (capacity < 0)
		capacity = 0;
	if ((uint64_t)capacity > (uint64_t)PY_SSIZE_T_MAX / sizeof(int32_t)) {
		lvp_py__release(&call);
		return PyErr_NoMemory();
	}
	int32_t *offsets = PyMem_Malloc(sizeof(int32_t) * ((size_t)vertex_count + 1));
	int32_t *bones = PyMem_Malloc(sizeof(int32_t) * (capacity ? (size_t)capacity : 1));
	float *values = PyMem_Malloc(sizeof(float) * (capacity ? (size_t)capacity : 1));
	PyObject *tuple = NULL;
	if (!offsets || !bones || !values) {
		lvp_py__release(&call);
		PyErr_NoMemory();
		goto done;
	}
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_auto_weights(offsets, bones, values, capacity, positions.data, vertex_count, triangles.data,
	                          triangle_count, &skeleton, &options, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end(&call, result) != 0)
		goto done;
	int32_t total = offsets[vertex_count];
	if (total < 0 || total > capacity) {
		PyErr_Format(PyExc_SystemError, "_lvp: auto_weights wrote %d influences into room for %lld.", (int)total,
		             (long long)capacity);
		goto done;
	}
	PyObject *arrays[3] = {
	    lvp_py__new_array("i", offsets, (Py_ssize_t)sizeof(int32_t) * ((Py_ssize_t)vertex_count + 1)),
	    lvp_py__new_array("i", bones, (Py_ssize_t)sizeof(int32_t) * total),
	    lvp_py__new_array("f", values, (Py_ssize_t)sizeof(float) * total),
	};
	if (arrays[0] && arrays[1] && arrays[2])
		tuple = PyTuple_Pack(3, arrays[0], arrays[1], arrays[2]);
	for (int i = 0; i < 3; ++i)
		Py_XDECREF(arrays[i]);
done:
	PyMem_Free(offsets);
	PyMem_Free(bones);
	PyMem_Free(values);
	return tuple;
}

/* ---- Binding ------------------------------------------------------------------------------------------ */

typedef struct lvp_py__binding {
	PyObject_HEAD
	lvp_binding *binding; /* NULL once closed */
	/* Nonzero while a call runs with the GIL released. It is only read and written with the GIL held, so it
	 * needs no atomics: another thread can only look at it while the running call has released the GIL. */
	int busy;
	lvp_mode mode;
} lvp_py__binding;

static int lvp_py__check_open(lvp_py__binding *self)
{
	if (self->binding)
		return 0;
	PyErr_SetString(PyExc_ValueError, "this Binding is closed; create a new Binding.");
	return -1;
}

/* Claims the binding for one call; lvp_py__leave() gives it back. The core's binding is used by one thread
 * at a time (lvp.h, THREADS AND MEMORY): a second caller is refused rather than queued, because waiting on
 * a busy binding from Blender's UI thread would freeze the interface. */
static int lvp_py__enter(lvp_py__binding *self)
{
	if (self->busy) {
		PyErr_SetString(PyExc_RuntimeError,
		                "this Binding is in use by another thread; a Binding serves one call at a time (give each "
		                "thread its own Binding).");
		return -1;
	}
	if (lvp_py__check_open(self) != 0)
		return -1;
	self->busy = 1;
	return 0;
}

static void lvp_py__leave(lvp_py__binding *self)
{
	self->busy = 0;
}

/* The six map arguments, shared by Binding() and set_map(). NULL = not given. */
typedef struct lvp_py__map_arguments {
	PyObject *map, *alpha, *beta, *painted, *region_bone_offsets, *region_bones;
} lvp_py__map_arguments;

static int lvp_py__take_map(lvp_py__call *call, lvp_map_options *r_map, const lvp_py__map_arguments *arguments,
                            int32_t vertex_count, int32_t bone_count)
{
	lvp_map_options map = lvp_bind_default_options().map;
	int map_index = (int)map.map;
	lvp_py__array painted, region_offsets, region_bones;
	if (lvp_py__parse_choice(call, arguments->map, "map", lvp_py__map_names, 5, &map_index) != 0 ||
	    lvp_py__parse_float(call, arguments->alpha, "alpha", &map.alpha) != 0 ||
	    lvp_py__parse_float(call, arguments->beta, "beta", &map.beta) != 0 ||
	    lvp_py__take(call, &painted, arguments->painted, "painted", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__take(call, &region_offsets, arguments->region_bone_offsets, "region_bone_offsets", LVP_PY__INT32,
	                 false, true) != 0 ||
	    lvp_py__take(call, &region_bones, arguments->region_bones, "region_bones", LVP_PY__INT32, false, true) != 0 ||
	    lvp_py__expect_count(call, &painted, vertex_count, "one per vertex") != 0)
		return -1;
	map.map = (lvp_map)map_index;
	if (region_offsets.given != region_bones.given) {
		const char *missing = region_offsets.given ? "region_bones" : "region_bone_offsets";
		return lvp_py__argument_error(
		    call, LVP_PY__NULL_ARGUMENT, missing,
		    "%s is None but %s is given; pass region_bone_offsets and region_bones together, or neither.", missing,
		    region_offsets.given ? "region_bone_offsets" : "region_bones");
	}
	if (region_offsets.given) {
		if (lvp_py__expect_count(call, &region_offsets, (Py_ssize_t)bone_count + 1, "one per bone, plus one") != 0)
			return -1;
		int32_t total = ((const int32_t *)region_offsets.data)[bone_count];
		if (region_bones.count != total)
			return lvp_py__argument_error(call, LVP_PY__INVALID_SIZE, "region_bones",
			                              "region_bones has %zd int32 values; expected %d, the number that "
			                              "region_bone_offsets[%d] (its last entry) announces.",
			                              region_bones.count, (int)total, (int)bone_count);
	}
	map.painted = painted.data;
	map.region_bone_offsets = region_offsets.data;
	map.region_bones = region_bones.data;
	*r_map = map;
	return 0;
}

static const lvp_py__rename lvp_py__bind_renames[] = {
    {"vertex_count", "rest_positions"}, {"bone_count", "rest_matrices"}, {NULL, NULL}};

static PyObject *lvp_py__binding_new(PyTypeObject *type, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"rest_positions", "triangles", "weight_offsets",      "weight_bones",
	                           "weight_values",  "rest_matrices", "heads",            "tails",
	                           "mode",           "map",       "alpha",               "beta",
	                           "painted",        "region_bone_offsets", "region_bones", "threads",
	                           "bone_groups",    "bulge_width", "parents", NULL};
	PyObject *rest_object, *triangles_object, *offsets_object, *bones_object, *values_object;
	PyObject *matrices_object, *heads_object, *tails_object, *mode = NULL, *threads = NULL, *groups_object = NULL;
	PyObject *bulge_width = NULL, *parents_object = NULL;
	lvp_py__map_arguments map_arguments = {NULL, NULL, NULL, NULL, NULL, NULL};
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OOOOOOOO|$OOOOOOOOOOO:Binding", keywords, &rest_object,
	                                 &triangles_object, &offsets_object, &bones_object, &values_object,
	                                 &matrices_object, &heads_object, &tails_object, &mode, &map_arguments.map,
	                                 &map_arguments.alpha, &map_arguments.beta, &map_arguments.painted,
	                                 &map_arguments.region_bone_offsets, &map_arguments.region_bones, &threads,
	                                 &groups_object, &bulge_width, &parents_object))
		return NULL;
	lvp_py__call call;
	lvp_bind_options options = lvp_bind_default_options();
	int mode_index = (int)options.mode;
	lvp_py__array rest, triangles, offsets, bones, values, groups, parents;
	const lvp_py__array *weight_parts[3] = {&offsets, &bones, &values};
	bool weights_given = false;
	lvp_skeleton skeleton;
	int32_t vertex_count = 0, triangle_count = 0;
	if (lvp_py__begin_method(&call, type, lvp_py__bind_renames) != 0 ||
	    lvp_py__parse_choice(&call, mode, "mode", lvp_py__mode_names, 2, &mode_index) != 0 ||
	    lvp_py__parse_int(&call, threads, "threads", &options.thread_count) != 0 ||
	    lvp_py__parse_float(&call, bulge_width, "bulge_width", &options.bulge_width) != 0 ||
	    lvp_py__take_mesh(&call, &rest, &triangles, rest_object, triangles_object, "rest_positions", &vertex_count,
	                      &triangle_count) != 0 ||
	    lvp_py__take(&call, &offsets, offsets_object, "weight_offsets", LVP_PY__INT32, false, true) != 0 ||
	    lvp_py__take(&call, &bones, bones_object, "weight_bones", LVP_PY__INT32, false, true) != 0 ||
	    lvp_py__take(&call, &values, values_object, "weight_values", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__take_skeleton(&call, &skeleton, matrices_object, heads_object, tails_object, true) != 0 ||
	    lvp_py__take_map(&call, &options.map, &map_arguments, vertex_count, skeleton.bone_count) != 0 ||
	    /* The weights come as a unit, like the skeleton; None for all three is a prop without bones. */
	    lvp_py__expect_together(&call, weight_parts, 3, "weight",
	                            "weight_offsets, weight_bones and weight_values", &weights_given) != 0 ||
	    (weights_given && lvp_py__expect_weights(&call, &offsets, &bones, &values, vertex_count) != 0) ||
	    lvp_py__take(&call, &groups, groups_object, "bone_groups", LVP_PY__INT32, false, true) != 0 ||
	    (skeleton.rest_matrices &&
	     lvp_py__expect_count(&call, &groups, skeleton.bone_count, "one per bone of rest_matrices") != 0) ||
	    lvp_py__take(&call, &parents, parents_object, "parents", LVP_PY__INT32, false, true) != 0 ||
	    (skeleton.rest_matrices &&
	     lvp_py__expect_count(&call, &parents, skeleton.bone_count, "one per bone of rest_matrices") != 0))
		return lvp_py__abandon(&call);
	options.mode = (lvp_mode)mode_index;
	skeleton.parents = parents.given && skeleton.rest_matrices ? parents.data : NULL;
	options.bone_groups = groups.given && skeleton.rest_matrices ? groups.data : NULL; /* none: the core says so */
	lvp_weights weights = {offsets.data, bones.data, values.data};
	lvp_binding *binding = NULL;
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_bind(&binding, rest.data, vertex_count, triangles.data, triangle_count,
	                  weights_given ? &weights : NULL, skeleton.rest_matrices ? &skeleton : NULL, &options,
	                  &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end(&call, result) != 0)
		return NULL;
	/* The type is final and not garbage-collected, so its tp_alloc is PyType_GenericAlloc. */
	lvp_py__binding *self = (lvp_py__binding *)PyType_GenericAlloc(type, 0);
	if (!self) {
		lvp_free(binding);
		return NULL;
	}
	self->binding = binding;
	self->busy = 0;
	self->mode = options.mode;
	return (PyObject *)self;
}

static void lvp_py__binding_dealloc(PyObject *object)
{
	/* A call in progress holds a reference to the object, so it cannot be busy here. */
	PyTypeObject *type = Py_TYPE(object);
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_free(self->binding);
	self->binding = NULL;
	PyObject_Free(object); /* the tp_free of a type without garbage collection */
	Py_DECREF(type);
}

static PyObject *lvp_py__binding_close(PyObject *object, PyObject *unused)
{
	(void)unused;
	lvp_py__binding *self = (lvp_py__binding *)object;
	if (!self->binding)
		Py_RETURN_NONE; /* like a file, closing twice is harmless */
	if (lvp_py__enter(self) != 0)
		return NULL;
	lvp_binding *binding = self->binding;
	self->binding = NULL;
	/* lvp_free() joins the binding's worker threads: let other Python threads run meanwhile. */
	Py_BEGIN_ALLOW_THREADS;
	lvp_free(binding);
	Py_END_ALLOW_THREADS;
	lvp_py__leave(self);
	Py_RETURN_NONE;
}

/* Starts a call of a Binding method: the binding claimed (lvp_py__enter) and the call begun. On failure
 * nothing is held and the error is set. */
static int lvp_py__begin_claimed(lvp_py__call *call, lvp_py__binding *self, const lvp_py__rename *renames)
{
	if (lvp_py__begin_method(call, Py_TYPE((PyObject *)self), renames) != 0)
		return -1;
	return lvp_py__enter(self);
}

/* Ends a Binding method's call: gives the binding back, releases the views, raises when the core's result
 * is a failure. Returns 0 on success. */
static int lvp_py__end_claimed(lvp_py__call *call, lvp_py__binding *self, lvp_result result)
{
	lvp_py__leave(self);
	return lvp_py__end(call, result);
}

/* Ends a Binding method's call whose arguments could not be taken: NULL, for the caller to return. */
static PyObject *lvp_py__abandon_claimed(lvp_py__call *call, lvp_py__binding *self)
{
	lvp_py__leave(self);
	return lvp_py__abandon(call);
}

static PyObject *lvp_py__binding_set_map(PyObject *object, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"map", "alpha", "beta", "painted", "region_bone_offsets", "region_bones", NULL};
	lvp_py__map_arguments map_arguments = {NULL, NULL, NULL, NULL, NULL, NULL};
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "|OOOOOO:set_map", keywords, &map_arguments.map,
	                                 &map_arguments.alpha, &map_arguments.beta, &map_arguments.painted,
	                                 &map_arguments.region_bone_offsets, &map_arguments.region_bones))
		return NULL;
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_py__call call;
	lvp_map_options map;
	if (lvp_py__begin_claimed(&call, self, NULL) != 0)
		return NULL;
	if (lvp_py__take_map(&call, &map, &map_arguments, lvp_vertex_count(self->binding), lvp_bone_count(self->binding)) !=
	    0)
		return lvp_py__abandon_claimed(&call, self);
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_set_map(self->binding, &map, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end_claimed(&call, self, result) != 0)
		return NULL;
	Py_RETURN_NONE;
}

/* Takes the per-frame inputs shared by correct() and region_volume_changes(). */
static int lvp_py__take_frame(lvp_py__call *call, lvp_py__array *r_positions, lvp_py__array *r_matrices,
                              lvp_py__array *r_rest, const lvp_binding *binding, PyObject *positions_object,
                              PyObject *matrices_object, PyObject *rest_object)
{
	Py_ssize_t vertex_values = (Py_ssize_t)lvp_vertex_count(binding) * 3;
	Py_ssize_t matrix_values = (Py_ssize_t)lvp_bone_count(binding) * 16;
	if (lvp_py__take(call, r_positions, positions_object, "positions", LVP_PY__FLOAT32, false, false) != 0 ||
	    lvp_py__take(call, r_matrices, matrices_object, "bone_matrices", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__take(call, r_rest, rest_object, "rest_positions", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__expect_count(call, r_positions, vertex_values, "3 per vertex of the binding") != 0 ||
	    lvp_py__expect_count(call, r_matrices, matrix_values, "16 per bone of the binding") != 0 ||
	    lvp_py__expect_count(call, r_rest, vertex_values, "3 per vertex of the binding") != 0)
		return -1;
	/* An empty buffer for a binding without bones stands for "no matrices", like None. */
	if (r_matrices->count == 0)
		r_matrices->data = NULL;
	return 0;
}

static const lvp_py__rename lvp_py__frame_renames[] = {{"vertex_count", "positions"},
                                                       {"bone_count", "bone_matrices"},
                                                       {"r_positions", "out_positions"},
                                                       {"r_offsets", "out_offsets"},
                                                       {"options.max_iterations", "iterations"},
                                                       {"options.rigid_space", "rigid_space"},
                                                       {"options.displacement_limit", "displacement_limit"},
                                                       {"options.restore", "restore"},
                                                       {"options.smoothing_passes", "smoothing_passes"},
                                                       {"r_changes", "positions"},
                                                       {NULL, NULL}};

static PyObject *lvp_py__binding_correct(PyObject *object, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"positions",  "bone_matrices", "out_positions", "out_offsets", "rest_positions",
	                           "iterations", "tolerance",     "fold_over",     "rigid_space", "displacement_limit",
	                           "restore",    "keep_apart",    "smoothing_passes", NULL};
	PyObject *positions_object, *matrices_object, *out_positions_object = NULL, *out_offsets_object = NULL;
	PyObject *rest_object = NULL, *iterations = NULL, *tolerance = NULL, *fold_over = NULL, *space_object = NULL;
	PyObject *limit = NULL, *restore = NULL, *keep_apart = NULL, *smoothing = NULL;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OO|$OOOOOOOOOOO:correct", keywords, &positions_object,
	                                 &matrices_object, &out_positions_object, &out_offsets_object, &rest_object,
	                                 &iterations, &tolerance, &fold_over, &space_object, &limit, &restore,
	                                 &keep_apart, &smoothing))
		return NULL;
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_py__call call;
	lvp_frame_options options = lvp_frame_default_options();
	int restore_index = options.restore;
	if (lvp_py__begin_method(&call, Py_TYPE(object), lvp_py__frame_renames) != 0 ||
	    lvp_py__parse_int(&call, iterations, "iterations", &options.max_iterations) != 0 ||
	    lvp_py__parse_float(&call, tolerance, "tolerance", &options.tolerance) != 0 ||
	    lvp_py__parse_bool(&call, fold_over, "fold_over", &options.fold_over) != 0 ||
	    lvp_py__parse_bool(&call, keep_apart, "keep_apart", &options.keep_apart) != 0 ||
	    lvp_py__parse_int(&call, smoothing, "smoothing_passes", &options.smoothing_passes) != 0 ||
	    lvp_py__parse_float(&call, limit, "displacement_limit", &options.displacement_limit) != 0 ||
	    lvp_py__parse_choice(&call, restore, "restore", lvp_py__restore_names, 2, &restore_index) != 0 ||
	    lvp_py__enter(self) != 0)
		return NULL;
	options.restore = restore_index;

	lvp_py__array positions, matrices, rest, out_positions, out_offsets, space;
	Py_ssize_t vertex_values = (Py_ssize_t)lvp_vertex_count(self->binding) * 3;
	if (lvp_py__take_frame(&call, &positions, &matrices, &rest, self->binding, positions_object, matrices_object,
	                       rest_object) != 0 ||
	    lvp_py__take(&call, &out_positions, out_positions_object, "out_positions", LVP_PY__FLOAT32, true, true) != 0 ||
	    lvp_py__take(&call, &out_offsets, out_offsets_object, "out_offsets", LVP_PY__FLOAT32, true, true) != 0 ||
	    lvp_py__expect_count(&call, &out_positions, vertex_values, "3 per vertex of the binding") != 0 ||
	    lvp_py__expect_count(&call, &out_offsets, vertex_values, "3 per vertex of the binding") != 0 ||
	    lvp_py__take(&call, &space, space_object, "rigid_space", LVP_PY__FLOAT32, false, true) != 0 ||
	    lvp_py__expect_count(&call, &space, 16, "a 4x4 matrix, row-major") != 0)
		return lvp_py__abandon_claimed(&call, self);
	options.rigid_space = space.given ? space.data : NULL;
	if (!out_positions.given && !out_offsets.given) {
		lvp_py__argument_error(&call, LVP_PY__NULL_ARGUMENT, "out_positions",
		                       "out_positions and out_offsets are both None; pass at least one float32 buffer of 3 "
		                       "values per vertex.");
		return lvp_py__abandon_claimed(&call, self);
	}
	/* The core corrects in place when out_positions is positions itself; any other sharing would mix reads
	 * and writes. */
	bool in_place = out_positions.data == positions.data && out_positions.bytes == positions.bytes;
	const lvp_py__array *inputs[] = {&matrices, &rest};
	const lvp_py__array *before_offsets[] = {&positions, &matrices, &rest, &out_positions};
	if ((!in_place && lvp_py__expect_apart(&call, &out_positions, &positions) != 0) ||
	    lvp_py__expect_apart_from_all(&call, &out_positions, inputs, 2) != 0 ||
	    lvp_py__expect_apart_from_all(&call, &out_offsets, before_offsets, 4) != 0)
		return lvp_py__abandon_claimed(&call, self);

	lvp_frame_stats stats;
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_correct(out_positions.data, out_offsets.data, self->binding, positions.data, matrices.data, rest.data,
	                     &options, &stats, &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end_claimed(&call, self, result) != 0)
		return NULL;
	return Py_BuildValue("{s:d,s:d,s:d,s:i,s:d,s:d,s:i,s:i,s:i,s:i,s:d,s:i,s:d,s:i,s:i,s:i,s:i,s:i,s:i,s:O}", "volume_rest",
	                     stats.volume_rest,
	                     "volume_before", stats.volume_before, "volume_after", stats.volume_after, "worst_region",
	                     (int)stats.worst_region, "worst_region_change_before", stats.worst_region_change_before,
	                     "worst_region_change_after", stats.worst_region_change_after, "iterations",
	                     (int)stats.iterations, "active_regions", (int)stats.active_regions, "skipped_regions",
	                     (int)stats.skipped_regions, "folded_vertices", (int)stats.folded_vertices,
	                     "max_displacement", stats.max_displacement, "passed_through", (int)stats.passed_through,
	                     "unskinned_distance", stats.unskinned_distance, "given_up_regions", (int)stats.given_up_regions,
	                     "given_up_region", (int)stats.given_up_region, "given_up_diverged",
	                     (int)stats.given_up_diverged, "shortened_vertices", (int)stats.shortened_vertices,
	                     "kept_apart_vertices", (int)stats.kept_apart_vertices,
	                     "crossing_triangles", (int)stats.crossing_triangles, "bones_scale",
	                     stats.bones_scale ? Py_True : Py_False);
}

static PyObject *lvp_py__binding_region_volume_changes(PyObject *object, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"positions", "bone_matrices", "rest_positions", NULL};
	PyObject *positions_object, *matrices_object, *rest_object = NULL;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "OO|O:region_volume_changes", keywords, &positions_object,
	                                 &matrices_object, &rest_object))
		return NULL;
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_py__call call;
	if (lvp_py__begin_claimed(&call, self, lvp_py__frame_renames) != 0)
		return NULL;
	Py_ssize_t region_count = lvp_region_count(self->binding);
	double *changes = PyMem_Malloc(sizeof(double) * 2 * (size_t)(region_count ? region_count : 1));
	if (!changes) {
		PyErr_NoMemory();
		return lvp_py__abandon_claimed(&call, self);
	}
	double *references = changes + region_count;
	lvp_py__array positions, matrices, rest;
	PyObject *tuple = NULL;
	if (lvp_py__take_frame(&call, &positions, &matrices, &rest, self->binding, positions_object, matrices_object,
	                       rest_object) != 0) {
		lvp_py__abandon_claimed(&call, self);
		goto done;
	}
	lvp_result result;
	Py_BEGIN_ALLOW_THREADS;
	result = lvp_region_volume_changes(changes, references, self->binding, positions.data, matrices.data, rest.data,
	                                   &call.diag);
	Py_END_ALLOW_THREADS;
	if (lvp_py__end_claimed(&call, self, result) != 0)
		goto done;
	PyObject *arrays[2] = {lvp_py__new_array("d", changes, (Py_ssize_t)sizeof(double) * region_count),
	                       lvp_py__new_array("d", references, (Py_ssize_t)sizeof(double) * region_count)};
	if (arrays[0] && arrays[1])
		tuple = PyTuple_Pack(2, arrays[0], arrays[1]);
	Py_XDECREF(arrays[0]);
	Py_XDECREF(arrays[1]);
done:
	PyMem_Free(changes);
	return tuple;
}

static PyObject *lvp_py__binding_segmentation(PyObject *object, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"out_vertex_regions", "out_triangle_regions", NULL};
	PyObject *vertex_object = NULL, *triangle_object = NULL;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "|OO:segmentation", keywords, &vertex_object, &triangle_object))
		return NULL;
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_py__call call;
	lvp_py__array vertex_regions, triangle_regions;
	if (lvp_py__begin_claimed(&call, self, NULL) != 0)
		return NULL;
	int32_t vertex_count = lvp_vertex_count(self->binding), triangle_count = lvp_triangle_count(self->binding);
	if (lvp_py__take(&call, &vertex_regions, vertex_object, "out_vertex_regions", LVP_PY__INT32, true, true) != 0 ||
	    lvp_py__take(&call, &triangle_regions, triangle_object, "out_triangle_regions", LVP_PY__INT32, true, true) !=
	        0 ||
	    lvp_py__expect_count(&call, &vertex_regions, vertex_count, "one per vertex of the binding") != 0 ||
	    lvp_py__expect_count(&call, &triangle_regions, triangle_count, "one per triangle of the binding") != 0 ||
	    lvp_py__expect_apart(&call, &vertex_regions, &triangle_regions) != 0)
		return lvp_py__abandon_claimed(&call, self);
	Py_BEGIN_ALLOW_THREADS;
	lvp_get_segmentation(self->binding, vertex_regions.data, triangle_regions.data);
	Py_END_ALLOW_THREADS;
	lvp_py__end_claimed(&call, self, lvp_success);
	Py_RETURN_NONE;
}

static PyObject *lvp_py__binding_correction_map(PyObject *object, PyObject *args, PyObject *kwargs)
{
	static char *keywords[] = {"out", NULL};
	PyObject *out_object;
	if (!PyArg_ParseTupleAndKeywords(args, kwargs, "O:correction_map", keywords, &out_object))
		return NULL;
	lvp_py__binding *self = (lvp_py__binding *)object;
	lvp_py__call call;
	lvp_py__array out;
	if (lvp_py__begin_claimed(&call, self, NULL) != 0)
		return NULL;
	if (lvp_py__take(&call, &out, out_object, "out", LVP_PY__FLOAT32, true, false) != 0 ||
	    lvp_py__expect_count(&call, &out, lvp_vertex_count(self->binding), "one per vertex of the binding") != 0)
		return lvp_py__abandon_claimed(&call, self);
	Py_BEGIN_ALLOW_THREADS;
	lvp_get_correction_map(self->binding, out.data);
	Py_END_ALLOW_THREADS;
	lvp_py__end_claimed(&call, self, lvp_success);
	Py_RETURN_NONE;
}

/* Which count a getter returns: the closure of lvp_py__binding_getset (ISO C has no function pointer in a
 * void *). */
enum { LVP_PY__VERTEX_COUNT, LVP_PY__TRIANGLE_COUNT, LVP_PY__BONE_COUNT, LVP_PY__REGION_COUNT,
       LVP_PY__FLIPPED_EDGE_COUNT };

/* The counts never change after bind, so reading them needs no claim on a busy binding. */
static PyObject *lvp_py__binding_count(PyObject *object, void *closure)
{
	lvp_py__binding *self = (lvp_py__binding *)object;
	if (lvp_py__check_open(self) != 0)
		return NULL;
	switch ((intptr_t)closure) {
	case LVP_PY__VERTEX_COUNT:
		return PyLong_FromLong(lvp_vertex_count(self->binding));
	case LVP_PY__TRIANGLE_COUNT:
		return PyLong_FromLong(lvp_triangle_count(self->binding));
	case LVP_PY__BONE_COUNT:
		return PyLong_FromLong(lvp_bone_count(self->binding));
	case LVP_PY__FLIPPED_EDGE_COUNT:
		return PyLong_FromLong(lvp_flipped_edge_count(self->binding));
	default:
		return PyLong_FromLong(lvp_region_count(self->binding));
	}
}

static PyObject *lvp_py__binding_repr(PyObject *object)
{
	lvp_py__binding *self = (lvp_py__binding *)object;
	if (!self->binding)
		return PyUnicode_FromString("<_lvp.Binding (closed)>");
	return PyUnicode_FromFormat("<_lvp.Binding %s, %d vertices, %d triangles, %d bones, %d regions>",
	                            lvp_py__mode_names[self->mode], (int)lvp_vertex_count(self->binding),
	                            (int)lvp_triangle_count(self->binding), (int)lvp_bone_count(self->binding),
	                            (int)lvp_region_count(self->binding));
}

#define LVP_PY__KEYWORDS(function) ((PyCFunction)(void (*)(void))(function))

static PyMethodDef lvp_py__binding_methods[] = {
    {"set_map", LVP_PY__KEYWORDS(lvp_py__binding_set_map), METH_VARARGS | METH_KEYWORDS,
     "set_map(map='ORGANIC', alpha=1.0, beta=1.0, painted=None, region_bone_offsets=None, region_bones=None)\n"
     "Replaces the correction map without rebinding."},
    {"correct", LVP_PY__KEYWORDS(lvp_py__binding_correct), METH_VARARGS | METH_KEYWORDS,
     "correct(positions, bone_matrices, *, out_positions=None, out_offsets=None, rest_positions=None, "
     "iterations=8, tolerance=1e-4, fold_over=False, rigid_space=None, displacement_limit=0.0, "
     "restore='EACH_REGION', keep_apart=False, smoothing_passes=0) -> dict\n"
     "Corrects one frame of skinned positions so every region keeps its rest volume; returns the frame's stats."},
    {"segmentation", LVP_PY__KEYWORDS(lvp_py__binding_segmentation), METH_VARARGS | METH_KEYWORDS,
     "segmentation(out_vertex_regions=None, out_triangle_regions=None)\n"
     "Writes the region of every vertex and/or triangle (int32, -1 = none)."},
    {"correction_map", LVP_PY__KEYWORDS(lvp_py__binding_correction_map), METH_VARARGS | METH_KEYWORDS,
     "correction_map(out)\nWrites the correction map per vertex (float32, maximum 1)."},
    {"region_volume_changes", LVP_PY__KEYWORDS(lvp_py__binding_region_volume_changes), METH_VARARGS | METH_KEYWORDS,
     "region_volume_changes(positions, bone_matrices, rest_positions=None) -> (changes, references)\n"
     "Volume change of every region (array('d')) and the reference volumes of the tolerance."},
    {"close", lvp_py__binding_close, METH_NOARGS, "close()\nFrees the binding now; further calls raise ValueError."},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef lvp_py__binding_getset[] = {
    {"vertex_count", lvp_py__binding_count, NULL, "Number of vertices.", (void *)LVP_PY__VERTEX_COUNT},
    {"triangle_count", lvp_py__binding_count, NULL, "Number of triangles.", (void *)LVP_PY__TRIANGLE_COUNT},
    {"bone_count", lvp_py__binding_count, NULL, "Number of bones (0 for a prop bound without a skeleton).",
     (void *)LVP_PY__BONE_COUNT},
    {"region_count", lvp_py__binding_count, NULL, "Number of regions: bone_count in LOCAL mode, 1 in GLOBAL.",
     (void *)LVP_PY__REGION_COUNT},
    {"flipped_edge_count", lvp_py__binding_count, NULL,
     "Edges shared by two triangles wound the same way (their normals point opposite ways): the local volumes "
     "there are wrong. 0 for a consistently oriented mesh.",
     (void *)LVP_PY__FLIPPED_EDGE_COUNT},
    {NULL, NULL, NULL, NULL, NULL},
};

/* CPython's slot tables hold functions in void * fields, which ISO C does not define but POSIX (dlsym) and
 * every compiler Python supports do: silence -Wpedantic for the two tables only. */
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic"
static PyType_Slot lvp_py__binding_slots[] = {
    {Py_tp_doc, "Binding(rest_positions, triangles, weight_offsets, weight_bones, weight_values, rest_matrices, "
                "heads, tails, *, mode='LOCAL', map='ORGANIC', alpha=1.0, beta=1.0, painted=None, "
                "region_bone_offsets=None, region_bones=None, threads=1, bone_groups=None, bulge_width=0.0, "
                "parents=None)\n"
                "A mesh bound to its skeleton and weights at rest; corrects frames. One call at a time per object."},
    {Py_tp_new, lvp_py__binding_new},
    {Py_tp_dealloc, lvp_py__binding_dealloc},
    {Py_tp_repr, lvp_py__binding_repr},
    {Py_tp_methods, lvp_py__binding_methods},
    {Py_tp_getset, lvp_py__binding_getset},
    {0, NULL},
};
#pragma GCC diagnostic pop

static PyType_Spec lvp_py__binding_spec = {
    .name = "_lvp.Binding",
    .basicsize = sizeof(lvp_py__binding),
    .itemsize = 0,
    .flags = Py_TPFLAGS_DEFAULT | Py_TPFLAGS_IMMUTABLETYPE,
    .slots = lvp_py__binding_slots,
};

/* ---- module ------------------------------------------------------------------------------------------- */

static PyMethodDef lvp_py__functions[] = {
    {"mesh_volume", LVP_PY__KEYWORDS(lvp_py__mesh_volume), METH_VARARGS | METH_KEYWORDS,
     "mesh_volume(positions, triangles) -> float\nSigned volume of a closed triangle mesh."},
    {"volume_gradient", LVP_PY__KEYWORDS(lvp_py__volume_gradient), METH_VARARGS | METH_KEYWORDS,
     "volume_gradient(out, positions, triangles)\nWrites the per-vertex volume gradient (float32[3N])."},
    {"vertex_normals", LVP_PY__KEYWORDS(lvp_py__vertex_normals), METH_VARARGS | METH_KEYWORDS,
     "vertex_normals(out, positions, triangles)\nWrites unit area-weighted vertex normals (float32[3N])."},
    {"skin_linear", LVP_PY__KEYWORDS(lvp_py__skin_linear), METH_VARARGS | METH_KEYWORDS,
     "skin_linear(out, rest_positions, weight_offsets, weight_bones, weight_values, skin_matrices)\n"
     "Linear blend skinning."},
    {"skin_dual_quaternion", LVP_PY__KEYWORDS(lvp_py__skin_dual_quaternion), METH_VARARGS | METH_KEYWORDS,
     "skin_dual_quaternion(out, rest_positions, weight_offsets, weight_bones, weight_values, skin_matrices)\n"
     "Dual quaternion skinning (Blender's Preserve Volume)."},
    {"compose_frames", LVP_PY__KEYWORDS(lvp_py__compose_frames), METH_VARARGS | METH_KEYWORDS,
     "compose_frames(out, premat, bone_matrices, joint_counts, joint_matrices, corrections=None)\n"
     "Posed frames from Blender's matrices (column by column): per bone premat @ bone, or premat @ bone @ joint "
     "per joint, then @ correction; written row by row, bit for bit as mathutils composes them."},
    {"auto_weights", LVP_PY__KEYWORDS(lvp_py__auto_weights), METH_VARARGS | METH_KEYWORDS,
     "auto_weights(positions, triangles, rest_matrices, heads, tails, *, alpha=2.0, visibility='NORMAL', "
     "normal_cos_max=0.0, max_influences=4, min_weight=0.01, smoothing_iterations=0, smoothing_length=0.0, "
     "by_length=True, smoothing_thickness=0.0, facing=False, heat=False, threads=1) "
     "-> (offsets, bones, values)\n"
     "Automatic skinning weights (paper 5.1) as compressed rows."},
    {NULL, NULL, 0, NULL},
};

static int lvp_py__exec(PyObject *module)
{
	lvp_py__state *state = PyModule_GetState(module);
	state->error = PyErr_NewExceptionWithDoc(
	    "_lvp.Error",
	    "An argument the core or this module refuses. A ValueError whose message starts with the argument's "
	    "name; .argument is that name (or None) and .code what is wrong, for code to branch on: the core's result "
	    "without its prefix ('mesh_not_closed', 'index_out_of_range', 'invalid_size'...), or 'invalid_buffer' for "
	    "an object that is not a buffer of the kind asked or that shares memory with another.",
	    PyExc_ValueError, NULL);
	if (!state->error || PyModule_AddObjectRef(module, "Error", state->error) != 0)
		return -1;
	PyObject *type = PyType_FromModuleAndSpec(module, &lvp_py__binding_spec, NULL);
	if (!type)
		return -1;
	int failed = PyModule_AddObjectRef(module, "Binding", type);
	Py_DECREF(type);
	if (failed)
		return -1;
	return PyModule_AddStringConstant(
	    module, "version", LVP_PY__VERSION_STRING(LVP_VERSION_MAJOR, LVP_VERSION_MINOR, LVP_VERSION_PATCH));
}

static int lvp_py__traverse(PyObject *module, visitproc visit, void *arg)
{
	lvp_py__state *state = PyModule_GetState(module);
	Py_VISIT(state ? state->error : NULL);
	return 0;
}

static int lvp_py__clear(PyObject *module)
{
	lvp_py__state *state = PyModule_GetState(module);
	if (state)
		Py_CLEAR(state->error);
	return 0;
}

static void lvp_py__free(void *module)
{
	lvp_py__clear((PyObject *)module);
}

#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wpedantic" /* a function in a void * field, as above */
static PyModuleDef_Slot lvp_py__module_slots[] = {
    {Py_mod_exec, lvp_py__exec},
    {0, NULL},
};
#pragma GCC diagnostic pop

static struct PyModuleDef lvp_py__module = {
    PyModuleDef_HEAD_INIT,
    .m_name = "_lvp",
    .m_doc = "Local volume preservation for skinned meshes (Rohmer, Hahmann, Cani 2008): the C core's Python "
             "interface. Buffers go through the buffer protocol; see docs/python_module.md.",
    .m_size = sizeof(lvp_py__state),
    .m_methods = lvp_py__functions,
    .m_slots = lvp_py__module_slots,
    .m_traverse = lvp_py__traverse,
    .m_clear = lvp_py__clear,
    .m_free = lvp_py__free,
};

PyMODINIT_FUNC PyInit__lvp(void)
{
	return PyModuleDef_Init(&lvp_py__module);
}
