/* The kernels' check of a float64 buffer argument (shared by the kernels in csrc/). */
#ifndef GUIDEDARM_CSRC_BUFFERS_H_
#define GUIDEDARM_CSRC_BUFFERS_H_

#define PY_SSIZE_T_CLEAN
#include <Python.h>

/* 1 if the buffer holds `count` doubles, else 0 with a ValueError naming it. */
static inline int Doubles(Py_buffer *b, Py_ssize_t count, const char *name) {
    if (b->len != count * (Py_ssize_t)sizeof(double)) {
        PyErr_Format(PyExc_ValueError, "%s: %zd doubles expected, got %zd bytes", name, count,
                     b->len);
        return 0;
    }
    return 1;
}

#endif  // GUIDEDARM_CSRC_BUFFERS_H_
