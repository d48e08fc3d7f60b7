/*
 * load_module.c - loads _lvp.pyd as Windows' CPython does and initialises it, under wine, against the
 * stub python3.dll of python3_stub.c (no Windows CPython is installed here).
 *
 *   load_module.exe PATH\_lvp.pyd VERSION FUNCTION...
 *
 * What CPython does for a module with multi-phase initialisation (PEP 489): LoadLibrary, find
 * PyInit__lvp, call it, take the PyModuleDef it returns, create a module object and run the
 * definition's Py_mod_exec slot on it. This program does the same and checks what the module did:
 * the definition is "_lvp" with exactly the functions named (run.sh names those of the Linux
 * module), and the exec slot created the type _lvp.Binding from its spec, added it as "Binding"
 * and added "version" = VERSION, and nothing else. Exit status 0 when all of that holds; the first
 * thing that does not is printed.
 */
#include <Python.h>

#include <stdio.h>
#include <string.h>
#include <windows.h>

/* From the stub python3.dll (python3_stub.c). */
PyObject *lvp_stub_new_module(void);
const char *lvp_stub_log(void);

static int fail(const char *what)
{
	fprintf(stderr, "load_module: %s\n", what);
	return 1;
}

int main(int argc, char **argv)
{
	if (argc < 3)
		return fail("usage: load_module.exe PATH\\_lvp.pyd VERSION FUNCTION...");
	/* Its import of python3.dll binds to the stub this program already loaded. */
	HMODULE library = LoadLibraryA(argv[1]);
	if (!library) {
		fprintf(stderr, "load_module: LoadLibrary(%s) failed, error %lu (126: a DLL it imports is missing, "
		                "127: a function it imports is missing)\n",
		        argv[1], (unsigned long)GetLastError());
		return 1;
	}
	printf("loaded %s\n", argv[1]);
	FARPROC entry = GetProcAddress(library, "PyInit__lvp");
	if (!entry)
		return fail("no PyInit__lvp exported");
	PyObject *(*init)(void) = (PyObject * (*)(void)) (void (*)(void))entry;
	PyModuleDef *def = (PyModuleDef *)init();
	if (!def)
		return fail("PyInit__lvp returned NULL");
	if (!def->m_name || strcmp(def->m_name, "_lvp") != 0)
		return fail("the module definition is not named _lvp");
	printf("PyInit__lvp returned the definition of %s (%s...)\n", def->m_name, def->m_doc ? "documented" : "no doc");

	int count = 0;
	for (PyMethodDef *method = def->m_methods; method && method->ml_name; ++method, ++count) {
		int named = 0;
		for (int i = 3; i < argc; ++i)
			named |= strcmp(method->ml_name, argv[i]) == 0;
		printf("  function %s\n", method->ml_name);
		if (!named || !method->ml_meth)
			return fail("a function that was not named, or without its C function");
	}
	if (count != argc - 3)
		return fail("fewer functions than were named");

	int exec_slots = 0;
	for (PyModuleDef_Slot *slot = def->m_slots; slot && slot->slot != 0; ++slot) {
		if (slot->slot != Py_mod_exec)
			continue;
		/* The slot holds a function in a void * (as CPython reads it); ISO C has no such cast. */
		int (*exec)(PyObject *);
		memcpy(&exec, &slot->value, sizeof(exec));
		if (exec(lvp_stub_new_module()) != 0)
			return fail("the module's exec slot failed");
		++exec_slots;
	}
	if (exec_slots != 1)
		return fail("expected one Py_mod_exec slot");

	char expected[1024];
	snprintf(expected, sizeof(expected),
	         "PyModuleDef_Init _lvp\n"
	         "PyModule_GetState module=yes\n"
	         "PyErr_NewExceptionWithDoc _lvp.Error doc=yes dict=none\n"
	         "PyModule_AddObjectRef Error module=yes value=exception\n"
	         "PyType_FromModuleAndSpec _lvp.Binding module=yes bases=none\n"
	         "PyModule_AddObjectRef Binding module=yes value=type\n"
	         "PyModule_AddStringConstant version=%s module=yes\n",
	         argv[2]);
	printf("calls into python3.dll:\n%s", lvp_stub_log());
	if (strcmp(lvp_stub_log(), expected) != 0) {
		fprintf(stderr, "load_module: expected these calls:\n%s", expected);
		return 1;
	}
	printf("initialised: _lvp %s\n", argv[2]);
	return 0;
}
