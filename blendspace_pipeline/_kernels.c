/* Compiled kernels of the measure stage's hottest loops (an optional extension module).

   Every function here is a faster way to a result the pure-Python code computes too, and must
   give that result to the bit: the callers fall back to numpy when the module is not built (no
   C compiler at install time) or when a kernel declines an input (returns False). The tests run
   both ways and compare bytes (tests/test_kernels.py).

   parse_decimals(block, out, frames, channels) -> bool
       The whitespace-separated numbers of a BVH MOTION block (bytes-like, ``frames`` lines of
       ``channels`` values) into the writable float64 buffer ``out``, channel-major: value c of
       frame f goes to out[c * frames + f]. Only the simplest spelling is taken,
       `-?digits[.digits][(e|E)[+-]digits]`, and only numbers that Clinger's fast path converts
       exactly: a significand of at most 2^53 scaled by 10^k, |k| <= 22, is one IEEE
       multiplication or division of two exact doubles, so it is rounded once, correctly: the
       value Python's float(), numpy and pyarrow give. Anything else (another spelling, more
       digits, a wrong count) returns False, and the caller's parsers decide and name the line.

   The build passes -ffp-contract=off (setup.py): a fused multiply-add would round once where
   numpy rounds twice. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <stdint.h>

/* x87 arithmetic (FLT_EVAL_METHOD 2) rounds to 80 bits first: the fast path would not be exact. */
#if defined(FLT_EVAL_METHOD) && FLT_EVAL_METHOD != 0
#define EXACT_DOUBLES 0
#else
#define EXACT_DOUBLES 1
#endif

static const double POWERS_OF_TEN[23] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22,
};

#define MAX_EXACT_SIGNIFICAND (UINT64_C(1) << 53)

static inline int is_space(unsigned char c) {
    /* What numpy's ``fromstring(sep=" ")`` skips between numbers (C isspace in the C locale). */
    return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\v' || c == '\f';
}

/* One number at p (not past end). Returns the position after it, or NULL to decline. */
static const unsigned char *parse_one(const unsigned char *p, const unsigned char *end, double *value) {
    int negative = 0;
    if (*p == '-') {
        negative = 1;
        p++;
    }
    uint64_t significand = 0;
    int digits = 0;     /* digits read, leading zeros of the significand not counted */
    int any_digit = 0;  /* a mantissa digit at all (zeros included) */
    int scale = 0;      /* power of ten of the last digit read */
    while (p < end && *p >= '0' && *p <= '9') {
        any_digit = 1;
        if (significand || *p != '0') {
            if (++digits > 19) return NULL; /* could overflow 64 bits: decline */
            significand = significand * 10 + (uint64_t)(*p - '0');
        }
        p++;
    }
    if (p < end && *p == '.') {
        p++;
        while (p < end && *p >= '0' && *p <= '9') {
            any_digit = 1;
            if (significand || *p != '0') {
                if (++digits > 19) return NULL;
                significand = significand * 10 + (uint64_t)(*p - '0');
            }
            scale--;
            p++;
        }
    }
    if (!any_digit) return NULL;
    if (p < end && (*p == 'e' || *p == 'E')) {
        p++;
        int exponent_negative = 0;
        if (p < end && (*p == '+' || *p == '-')) {
            exponent_negative = *p == '-';
            p++;
        }
        if (p >= end || *p < '0' || *p > '9') return NULL;
        int exponent = 0;
        while (p < end && *p >= '0' && *p <= '9') {
            if (exponent > 10000) return NULL;
            exponent = exponent * 10 + (*p - '0');
            p++;
        }
        scale += exponent_negative ? -exponent : exponent;
    }
    if (p < end && !is_space(*p)) return NULL; /* a comma, a letter, a second point: decline */
    double magnitude;
    if (significand == 0) {
        magnitude = 0.0;
    } else {
        if (significand > MAX_EXACT_SIGNIFICAND || scale < -22 || scale > 22) return NULL;
        magnitude = scale >= 0 ? (double)significand * POWERS_OF_TEN[scale]
                               : (double)significand / POWERS_OF_TEN[-scale];
    }
    *value = negative ? -magnitude : magnitude;
    return p;
}

static PyObject *parse_decimals(PyObject *self, PyObject *args) {
    Py_buffer text, out;
    Py_ssize_t frames, channels;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*w*nn", &text, &out, &frames, &channels)) return NULL;
    int ok = EXACT_DOUBLES && frames > 0 && channels > 0 &&
             out.len == (Py_ssize_t)(frames * channels * (Py_ssize_t)sizeof(double)) &&
             PyBuffer_IsContiguous(&out, 'C');
    if (ok) {
        const unsigned char *p = (const unsigned char *)text.buf;
        const unsigned char *end = p + text.len;
        double *values = (double *)out.buf;
        Py_ssize_t frame = 0, channel = 0;
        Py_BEGIN_ALLOW_THREADS
        for (;;) {
            while (p < end && is_space(*p)) p++;
            if (p >= end) break;
            if (frame >= frames) { /* one value too many */
                ok = 0;
                break;
            }
            double value;
            p = parse_one(p, end, &value);
            if (p == NULL) {
                ok = 0;
                break;
            }
            values[channel * frames + frame] = value; /* channel-major: (channels, frames) */
            if (++channel == channels) {
                channel = 0;
                frame++;
            }
        }
        if (frame != frames || channel != 0) ok = 0; /* too few values */
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&text);
    PyBuffer_Release(&out);
    return PyBool_FromLong(ok);
}

/* forward_kinematics(local_rot, local_pos, parents, world_rot, world_pos, frames) -> bool
   World rotations and positions of every joint on every frame: (F, J, 4) quaternions (x, y, z,
   w) and (F, J, 3) positions, C-contiguous float64; ``parents`` is int64 (J,), -1 for a root,
   each parent before its children. The terms are `quaternions.multiply` and
   `quaternions.rotate`'s, in their order (motion/clip.py `forward_kinematics`), one IEEE
   operation at a time, so the values are numpy's to the bit. False (nothing computed) when the
   sizes disagree or a parent comes after its child. */
static PyObject *forward_kinematics(PyObject *self, PyObject *args) {
    Py_buffer local_rot, local_pos, parents_buffer, world_rot, world_pos;
    (void)self;
    Py_ssize_t frames;
    if (!PyArg_ParseTuple(args, "y*y*y*w*w*n", &local_rot, &local_pos, &parents_buffer, &world_rot, &world_pos,
                          &frames))
        return NULL;
    Py_ssize_t joints = parents_buffer.len / (Py_ssize_t)sizeof(int64_t);
    const int64_t *parents = (const int64_t *)parents_buffer.buf;
    int ok = EXACT_DOUBLES && joints > 0 && frames > 0 && parents_buffer.len == joints * (Py_ssize_t)sizeof(int64_t) &&
             local_rot.len == frames * joints * 4 * (Py_ssize_t)sizeof(double) &&
             local_pos.len == frames * joints * 3 * (Py_ssize_t)sizeof(double) &&
             world_rot.len == local_rot.len && world_pos.len == local_pos.len &&
             PyBuffer_IsContiguous(&local_rot, 'C') && PyBuffer_IsContiguous(&local_pos, 'C') &&
             PyBuffer_IsContiguous(&world_rot, 'C') && PyBuffer_IsContiguous(&world_pos, 'C');
    for (Py_ssize_t j = 0; ok && j < joints; j++)
        if (parents[j] >= j || parents[j] < -1) ok = 0;
    if (ok) {
        const double *lr = (const double *)local_rot.buf, *lp = (const double *)local_pos.buf;
        double *wr = (double *)world_rot.buf, *wp = (double *)world_pos.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t f = 0; f < frames; f++) {
            const double *fr = lr + f * joints * 4, *fp = lp + f * joints * 3;
            double *gr = wr + f * joints * 4, *gp = wp + f * joints * 3;
            for (Py_ssize_t j = 0; j < joints; j++) {
                const double *b = fr + j * 4, *v = fp + j * 3;
                double *out = gr + j * 4, *moved = gp + j * 3;
                int64_t p = parents[j];
                if (p < 0) {
                    out[0] = b[0], out[1] = b[1], out[2] = b[2], out[3] = b[3];
                    moved[0] = v[0], moved[1] = v[1], moved[2] = v[2];
                    continue;
                }
                const double *a = gr + p * 4, *base = gp + p * 3;
                double ax = a[0], ay = a[1], az = a[2], aw = a[3];
                double bx = b[0], by = b[1], bz = b[2], bw = b[3];
                /* Each parenthesis is one rounding, in numpy's order (no contraction: setup.py). */
                out[0] = ((aw * bx + ax * bw) + ay * bz) - az * by;
                out[1] = ((aw * by - ax * bz) + ay * bw) + az * bx;
                out[2] = ((aw * bz + ax * by) - ay * bx) + az * bw;
                out[3] = ((aw * bw - ax * bx) - ay * by) - az * bz;
                double vx = v[0], vy = v[1], vz = v[2];
                double tx = 2.0 * (ay * vz - az * vy);
                double ty = 2.0 * (az * vx - ax * vz);
                double tz = 2.0 * (ax * vy - ay * vx);
                moved[0] = base[0] + ((vx + aw * tx) + (ay * tz - az * ty));
                moved[1] = base[1] + ((vy + aw * ty) + (az * tx - ax * tz));
                moved[2] = base[2] + ((vz + aw * tz) + (ax * ty - ay * tx));
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&local_rot);
    PyBuffer_Release(&local_pos);
    PyBuffer_Release(&parents_buffer);
    PyBuffer_Release(&world_rot);
    PyBuffer_Release(&world_pos);
    return PyBool_FromLong(ok);
}

static PyMethodDef methods[] = {
    {"forward_kinematics", forward_kinematics, METH_VARARGS,
     "forward_kinematics(local_rot, local_pos, parents, world_rot, world_pos, frames) -> bool: world "
     "transforms of every joint, numpy's to the bit, or False to let numpy compute them."},
    {"parse_decimals", parse_decimals, METH_VARARGS,
     "parse_decimals(block, out, frames, channels) -> bool: the numbers of a BVH MOTION block, "
     "channel-major, or False to let the pure-Python parsers decide."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {
    PyModuleDef_HEAD_INIT, "_kernels",
    "Compiled kernels of the measure stage (optional; see _kernels.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
