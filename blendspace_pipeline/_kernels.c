/* Compiled kernels of the hottest loops: reading and posing clips, and drawing the PNG (an optional
   extension module).

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

   draw_lines, stamp_markers, blend_spans, box_mean, box_mean_bytes
       The PNG's rasteriser (report/png.py); see their comments below.

   slerp(a, b, t, out, count)
       Quaternion slerp (motion/quaternions.py), used where numpy's acos and sin are the C
       library's (numpy's own SIMD versions may round differently on other CPUs).

   The build passes -ffp-contract=off (setup.py): a fused multiply-add would round once where
   numpy rounds twice. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <float.h>
#include <math.h>
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

/* slerp(a, b, t, out, count) -> bool
   Spherical interpolation of ``count`` quaternion pairs (float64 (count, 4) buffers ``a``, ``b``,
   ``out``; one float64 ``t`` per pair), as `quaternions.slerp` computes it: the dot product summed
   left to right, ``b`` negated where it is negative (the shortest arc), the angle from acos of
   the clipped |dot|, the weights sin((1 - t) theta) / sin(theta) and sin(t theta) / sin(theta)
   (1 - t and t where sin(theta) < 1e-6), and the result divided by its length (by 1 where it is
   0). acos and sin are the C library's: the caller uses this only where numpy's agree with them
   (`quaternions._libm_agrees`). False (nothing computed) on wrong sizes. */
static PyObject *slerp(PyObject *self, PyObject *args) {
    Py_buffer a_buffer, b_buffer, t_buffer, out_buffer;
    Py_ssize_t count;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*y*y*w*n", &a_buffer, &b_buffer, &t_buffer, &out_buffer, &count)) return NULL;
    Py_ssize_t size = count * 4 * (Py_ssize_t)sizeof(double);
    int ok = EXACT_DOUBLES && count >= 0 && a_buffer.len == size && b_buffer.len == size &&
             out_buffer.len == size && t_buffer.len == count * (Py_ssize_t)sizeof(double) &&
             PyBuffer_IsContiguous(&a_buffer, 'C') && PyBuffer_IsContiguous(&b_buffer, 'C') &&
             PyBuffer_IsContiguous(&t_buffer, 'C') && PyBuffer_IsContiguous(&out_buffer, 'C');
    if (ok) {
        const double *a = (const double *)a_buffer.buf, *b = (const double *)b_buffer.buf;
        const double *t = (const double *)t_buffer.buf;
        double *out = (double *)out_buffer.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t i = 0; i < count; i++) {
            const double *p = a + i * 4, *q = b + i * 4;
            double dot = ((p[0] * q[0] + p[1] * q[1]) + p[2] * q[2]) + p[3] * q[3];
            double sign = dot < 0.0 ? -1.0 : 1.0; /* -b is exact: only the sign bit changes */
            dot = fabs(dot);
            double clipped = dot > 1.0 ? 1.0 : (dot < -1.0 ? -1.0 : dot); /* NaN stays NaN, as np.clip */
            double theta = acos(clipped);
            double sin_theta = sin(theta);
            int small = sin_theta < 1e-6;
            double safe = small ? 1.0 : sin_theta;
            double ti = t[i];
            double wa = small ? 1.0 - ti : sin((1.0 - ti) * theta) / safe;
            double wb = small ? ti : sin(ti * theta) / safe;
            double r[4];
            for (int k = 0; k < 4; k++) r[k] = wa * p[k] + wb * (sign * q[k]);
            double norm = sqrt(((r[0] * r[0] + r[1] * r[1]) + r[2] * r[2]) + r[3] * r[3]);
            double divisor = norm == 0.0 ? 1.0 : norm;
            for (int k = 0; k < 4; k++) out[i * 4 + k] = r[k] / divisor;
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&a_buffer);
    PyBuffer_Release(&b_buffer);
    PyBuffer_Release(&t_buffer);
    PyBuffer_Release(&out_buffer);
    return PyBool_FromLong(ok);
}

/* ---- the PNG's rasteriser (report/png.py `_Pen`, `_blend_spans`, the box filter) ----------------

   The canvas is the (height, width, 3) float32 image, C-contiguous. Each kernel is the numpy code
   beside its caller, one IEEE operation at a time in numpy's order (float32 where numpy computes
   in float32), and declines (False, the canvas untouched) whatever that code would read
   differently: wrong sizes, spans outside the canvas, an index outside its table. */

/* Coordinates are declined beyond 2^26 pixels: a NaN cast to int64, or a line so long that drawing
   it pixel by pixel would not end (numpy's arrays for it would not fit in memory either). */
#define MAX_PIXEL (INT64_C(1) << 26)

static int canvas_ok(const Py_buffer *canvas, Py_ssize_t height, Py_ssize_t width) {
    return EXACT_DOUBLES && height >= 0 && width >= 0 &&
           canvas->len == height * width * 3 * (Py_ssize_t)sizeof(float) && PyBuffer_IsContiguous(canvas, 'C');
}

static int int64s_ok(const Py_buffer *buffer, Py_ssize_t count) {
    return buffer->len == count * (Py_ssize_t)sizeof(int64_t) && PyBuffer_IsContiguous(buffer, 'C');
}

/* draw_lines(canvas, height, width, starts, ends, (r, g, b)) -> bool
   One-pixel lines from int64 (x, y) ``starts[i]`` to ``ends[i]``: max(|dx|, |dy|) + 1 pixels,
   pixel k at rint(a + k / max(steps - 1, 1) * (b - a)) (`_Pen.lines`), opaque; pixels off the
   canvas are skipped. */
static PyObject *draw_lines(PyObject *self, PyObject *args) {
    Py_buffer canvas, starts, ends;
    Py_ssize_t height, width;
    double r, g, b;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nny*y*(ddd)", &canvas, &height, &width, &starts, &ends, &r, &g, &b))
        return NULL;
    Py_ssize_t lines = starts.len / (Py_ssize_t)(2 * sizeof(int64_t));
    int ok = canvas_ok(&canvas, height, width) && int64s_ok(&starts, 2 * lines) && int64s_ok(&ends, 2 * lines);
    for (Py_ssize_t i = 0; ok && i < 2 * lines; i++) {
        int64_t p = ((const int64_t *)starts.buf)[i], q = ((const int64_t *)ends.buf)[i];
        if (p > MAX_PIXEL || p < -MAX_PIXEL || q > MAX_PIXEL || q < -MAX_PIXEL) ok = 0;
    }
    if (ok) {
        const float colour[3] = {(float)r, (float)g, (float)b};
        float *pixels = (float *)canvas.buf;
        const int64_t *a = (const int64_t *)starts.buf, *e = (const int64_t *)ends.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t i = 0; i < lines; i++) {
            int64_t ax = a[2 * i], ay = a[2 * i + 1], dx = e[2 * i] - ax, dy = e[2 * i + 1] - ay;
            int64_t steps = (dx < 0 ? -dx : dx) > (dy < 0 ? -dy : dy) ? (dx < 0 ? -dx : dx) : (dy < 0 ? -dy : dy);
            steps += 1;
            double denominator = (double)(steps > 1 ? steps - 1 : 1);
            for (int64_t k = 0; k < steps; k++) {
                double along = (double)k / denominator;
                int64_t x = (int64_t)rint((double)ax + along * (double)dx);
                int64_t y = (int64_t)rint((double)ay + along * (double)dy);
                if (x < 0 || x >= width || y < 0 || y >= height) continue;
                float *pixel = pixels + (y * width + x) * 3;
                pixel[0] = colour[0], pixel[1] = colour[1], pixel[2] = colour[2];
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&canvas);
    PyBuffer_Release(&starts);
    PyBuffer_Release(&ends);
    return PyBool_FromLong(ok);
}

/* stamp_markers(canvas, height, width, centres, kinds, template, side, palette) -> bool
   Marker i (int64 centre (x, y), kind k) stamps ``template[k]`` (int64, side x side, centred;
   a palette index per pixel, -1 for none) onto the canvas, marker after marker: a later marker
   covers an earlier one, as `_Pen.markers`' z-buffer keeps the last. ``palette``: float32 RGB. */
static PyObject *stamp_markers(PyObject *self, PyObject *args) {
    Py_buffer canvas, centres, kinds, template_buffer, palette_buffer;
    Py_ssize_t height, width, side;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nny*y*y*ny*", &canvas, &height, &width, &centres, &kinds, &template_buffer,
                          &side, &palette_buffer))
        return NULL;
    Py_ssize_t markers = kinds.len / (Py_ssize_t)sizeof(int64_t);
    Py_ssize_t cells = side > 0 ? side * side : 1;
    Py_ssize_t templates = template_buffer.len / (Py_ssize_t)sizeof(int64_t) / cells;
    Py_ssize_t colours = palette_buffer.len / (Py_ssize_t)(3 * sizeof(float));
    int ok = canvas_ok(&canvas, height, width) && side > 0 && side % 2 == 1 && int64s_ok(&kinds, markers) &&
             int64s_ok(&centres, 2 * markers) && int64s_ok(&template_buffer, templates * cells) &&
             palette_buffer.len == colours * 3 * (Py_ssize_t)sizeof(float) &&
             PyBuffer_IsContiguous(&palette_buffer, 'C');
    const int64_t *kind = (const int64_t *)kinds.buf, *template = (const int64_t *)template_buffer.buf;
    for (Py_ssize_t i = 0; ok && i < markers; i++)
        if (kind[i] < 0 || kind[i] >= templates) ok = 0;
    for (Py_ssize_t i = 0; ok && i < 2 * markers; i++) {
        int64_t c = ((const int64_t *)centres.buf)[i];
        if (c > MAX_PIXEL || c < -MAX_PIXEL) ok = 0;
    }
    for (Py_ssize_t i = 0; ok && i < templates * cells; i++)
        if (template[i] < -1 || template[i] >= colours) ok = 0;
    if (ok) {
        float *pixels = (float *)canvas.buf;
        const float *palette = (const float *)palette_buffer.buf;
        const int64_t *centre = (const int64_t *)centres.buf, reach = side / 2;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t i = 0; i < markers; i++) {
            const int64_t *cell = template + kind[i] * cells;
            for (int64_t oy = 0; oy < side; oy++) {
                int64_t y = centre[2 * i + 1] + oy - reach;
                if (y < 0 || y >= height) continue;
                for (int64_t ox = 0; ox < side; ox++) {
                    int64_t x = centre[2 * i] + ox - reach, index = cell[oy * side + ox];
                    if (index < 0 || x < 0 || x >= width) continue;
                    float *pixel = pixels + (y * width + x) * 3;
                    const float *colour = palette + index * 3;
                    pixel[0] = colour[0], pixel[1] = colour[1], pixel[2] = colour[2];
                }
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&canvas);
    PyBuffer_Release(&centres);
    PyBuffer_Release(&kinds);
    PyBuffer_Release(&template_buffer);
    PyBuffer_Release(&palette_buffer);
    return PyBool_FromLong(ok);
}

/* blend_spans(canvas, height, width, rows, first, last, levels, (r, g, b), period, on) -> bool
   Pixel-row spans (int64 row, first and last column, inclusive, inside the canvas) of shapes
   of one colour: a pixel covered by k of them becomes v + L * (colour - v), in float32, with
   L = levels[min(k, len(levels) - 1)] (float32; `_blend_spans`). With ``period`` > 0 only the
   pixels where (row + column) % period < ``on`` (the hatching's stripes). Spans are counted
   row by row (a difference array along the row), so the memory is the spans plus one row. */
static PyObject *blend_spans(PyObject *self, PyObject *args) {
    Py_buffer canvas, rows_buffer, first_buffer, last_buffer, levels_buffer;
    Py_ssize_t height, width, period, on;
    double r, g, b;
    (void)self;
    if (!PyArg_ParseTuple(args, "w*nny*y*y*y*(ddd)nn", &canvas, &height, &width, &rows_buffer, &first_buffer,
                          &last_buffer, &levels_buffer, &r, &g, &b, &period, &on))
        return NULL;
    Py_ssize_t spans = rows_buffer.len / (Py_ssize_t)sizeof(int64_t);
    Py_ssize_t steps = levels_buffer.len / (Py_ssize_t)sizeof(float);
    int ok = canvas_ok(&canvas, height, width) && int64s_ok(&rows_buffer, spans) &&
             int64s_ok(&first_buffer, spans) && int64s_ok(&last_buffer, spans) && steps > 0 &&
             levels_buffer.len == steps * (Py_ssize_t)sizeof(float) && PyBuffer_IsContiguous(&levels_buffer, 'C') &&
             period >= 0;
    const int64_t *row = (const int64_t *)rows_buffer.buf, *first = (const int64_t *)first_buffer.buf,
                  *last = (const int64_t *)last_buffer.buf;
    for (Py_ssize_t s = 0; ok && s < spans; s++)
        if (row[s] < 0 || row[s] >= height || first[s] < 0 || first[s] > last[s] || last[s] >= width) ok = 0;
    Py_ssize_t *start = NULL, *order = NULL;
    int64_t *difference = NULL;
    if (ok && spans) {
        start = (Py_ssize_t *)PyMem_RawCalloc((size_t)height + 1, sizeof(Py_ssize_t));
        order = (Py_ssize_t *)PyMem_RawMalloc((size_t)spans * sizeof(Py_ssize_t));
        difference = (int64_t *)PyMem_RawCalloc((size_t)width + 1, sizeof(int64_t));
        if (start == NULL || order == NULL || difference == NULL) {
            PyMem_RawFree(start), PyMem_RawFree(order), PyMem_RawFree(difference);
            PyBuffer_Release(&canvas), PyBuffer_Release(&rows_buffer), PyBuffer_Release(&first_buffer);
            PyBuffer_Release(&last_buffer), PyBuffer_Release(&levels_buffer);
            return PyErr_NoMemory();
        }
    }
    if (ok && spans) {
        const float colour[3] = {(float)r, (float)g, (float)b};
        const float *levels = (const float *)levels_buffer.buf;
        float *pixels = (float *)canvas.buf;
        Py_BEGIN_ALLOW_THREADS
        /* The spans by row (a counting sort): start[y] .. start[y + 1] are row y's. */
        for (Py_ssize_t s = 0; s < spans; s++) start[row[s] + 1]++;
        for (Py_ssize_t y = 0; y < height; y++) start[y + 1] += start[y];
        for (Py_ssize_t s = 0; s < spans; s++) order[start[row[s]]++] = s;
        for (Py_ssize_t y = height; y > 0; y--) start[y] = start[y - 1];
        start[0] = 0;
        for (Py_ssize_t y = 0; y < height; y++) {
            if (start[y] == start[y + 1]) continue;
            int64_t low = width, high = -1;
            for (Py_ssize_t i = start[y]; i < start[y + 1]; i++) {
                Py_ssize_t s = order[i];
                difference[first[s]] += 1;
                difference[last[s] + 1] -= 1;
                if (first[s] < low) low = first[s];
                if (last[s] > high) high = last[s];
            }
            int64_t count = 0;
            for (int64_t x = low; x <= high; x++) {
                count += difference[x];
                difference[x] = 0;
                if (count <= 0 || (period > 0 && (y + x) % period >= on)) continue;
                float level = levels[count < steps ? count : steps - 1];
                float *pixel = pixels + (y * width + x) * 3;
                for (int c = 0; c < 3; c++) {
                    float change = colour[c] - pixel[c];
                    change = level * change;
                    pixel[c] = pixel[c] + change;
                }
            }
            difference[high + 1] = 0;
        }
        Py_END_ALLOW_THREADS
    }
    PyMem_RawFree(start);
    PyMem_RawFree(order);
    PyMem_RawFree(difference);
    PyBuffer_Release(&canvas);
    PyBuffer_Release(&rows_buffer);
    PyBuffer_Release(&first_buffer);
    PyBuffer_Release(&last_buffer);
    PyBuffer_Release(&levels_buffer);
    return PyBool_FromLong(ok);
}

/* The sum of sample i (pixel i / 3, channel i % 3) of one output row over its scale x scale block
   of canvas rows starting at ``top`` (``row`` floats each): 0 + the block's first pixel, plus the
   others in row-major order, in float32, as `_box_mean` sums the strided views. Scale 2, the
   PNG's, is spelled out (the same four terms in the same order). */
static inline float block_sum(const float *top, Py_ssize_t row, Py_ssize_t i, Py_ssize_t scale) {
    const Py_ssize_t x = i / 3, c = i % 3;
    if (scale == 2) {
        const float *block = top + x * 6 + c;
        float sum = 0.0f + block[0];
        sum += block[3];
        sum += block[row];
        sum += block[row + 3];
        return sum;
    }
    float sum = 0.0f + top[x * scale * 3 + c];
    for (Py_ssize_t dy = 0; dy < scale; dy++)
        for (Py_ssize_t dx = dy ? 0 : 1; dx < scale; dx++) sum += top[dy * row + (x * scale + dx) * 3 + c];
    return sum;
}

/* box_mean(canvas, height, width, out, scale) -> bool
   The mean of every scale x scale block of the canvas into ``out`` ((height / scale,
   width / scale, 3) float32): 0 + the block's first pixel, plus the others in row-major order,
   divided by scale * scale, in float32, as `_pixels` sums the strided views. ``out`` may be the
   start of ``canvas`` itself: in this loop order every block is read before a write reaches it
   (the write of block (y, x) lands below its own first input, and no pointer is `restrict`). */
static PyObject *box_mean(PyObject *self, PyObject *args) {
    Py_buffer canvas, out;
    Py_ssize_t height, width, scale;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnw*n", &canvas, &height, &width, &out, &scale)) return NULL;
    int ok = canvas_ok(&canvas, height, width) && scale > 0 && height % scale == 0 && width % scale == 0 &&
             canvas_ok(&out, height / scale, width / scale);
    if (ok) {
        const float *in = (const float *)canvas.buf;
        float *mean = (float *)out.buf;
        const float blocks = (float)(scale * scale);
        const Py_ssize_t row = width * 3, columns = width / scale;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t y = 0; y < height / scale; y++)
            for (Py_ssize_t i = 0; i < columns * 3; i++)
                mean[y * columns * 3 + i] = block_sum(in + (y * scale) * row, row, i, scale) / blocks;
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&canvas);
    PyBuffer_Release(&out);
    return PyBool_FromLong(ok);
}

/* box_mean_bytes(canvas, height, width, out, scale) -> bool
   What `write_png` makes of `box_mean`'s result, in the same pass: each mean (the same float32
   sum and division) times 255 in float32, rounded half to even (rint in the default rounding
   mode, as numpy's rint), clipped to 0..255 and stored as a byte in ``out`` ((height / scale) *
   (width / scale) * 3 bytes). ``out`` may be the start of ``canvas``: byte j is written after
   every read of the float it lies in (float j / 4, which belongs to an earlier block). */
static PyObject *box_mean_bytes(PyObject *self, PyObject *args) {
    Py_buffer canvas, out;
    Py_ssize_t height, width, scale;
    (void)self;
    if (!PyArg_ParseTuple(args, "y*nnw*n", &canvas, &height, &width, &out, &scale)) return NULL;
    int ok = canvas_ok(&canvas, height, width) && scale > 0 && height % scale == 0 && width % scale == 0 &&
             out.len == (height / scale) * (width / scale) * 3 && PyBuffer_IsContiguous(&out, 'C');
    if (ok) {
        const float *in = (const float *)canvas.buf;
        unsigned char *bytes = (unsigned char *)out.buf;
        const float blocks = (float)(scale * scale);
        const Py_ssize_t row = width * 3, columns = width / scale;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t y = 0; y < height / scale; y++) {
            const float *top = in + (y * scale) * row;
            unsigned char *line = bytes + y * columns * 3;
            for (Py_ssize_t i = 0; i < columns * 3; i++) {
                float value = (block_sum(top, row, i, scale) / blocks) * 255.0f;
                /* Clipped first (the same result: 0 and 255 are whole numbers, and rounding keeps
                   order), so NaN, which no colour makes, becomes 0 instead of undefined behaviour. */
                value = value > 0.0f ? (value < 255.0f ? value : 255.0f) : 0.0f;
                /* Half to even, as rint in the default rounding mode: at 2^23 a float's step is 1,
                   so the addition rounds to a whole number and the subtraction is exact. */
                value = (value + 8388608.0f) - 8388608.0f;
                line[i] = (unsigned char)value;
            }
        }
        Py_END_ALLOW_THREADS
    }
    PyBuffer_Release(&canvas);
    PyBuffer_Release(&out);
    return PyBool_FromLong(ok);
}

static PyMethodDef methods[] = {
    {"draw_lines", draw_lines, METH_VARARGS,
     "draw_lines(canvas, height, width, starts, ends, rgb) -> bool: one-pixel lines, as _Pen.lines draws them."},
    {"stamp_markers", stamp_markers, METH_VARARGS,
     "stamp_markers(canvas, height, width, centres, kinds, template, side, palette) -> bool: markers in "
     "order, a later one on top."},
    {"blend_spans", blend_spans, METH_VARARGS,
     "blend_spans(canvas, height, width, rows, first, last, levels, rgb, period, on) -> bool: translucent "
     "pixel-row spans, k overlapping ones at levels[k]."},
    {"box_mean", box_mean, METH_VARARGS,
     "box_mean(canvas, height, width, out, scale) -> bool: the mean of every scale x scale block."},
    {"box_mean_bytes", box_mean_bytes, METH_VARARGS,
     "box_mean_bytes(canvas, height, width, out, scale) -> bool: box_mean as 8-bit PNG samples."},

    {"slerp", slerp, METH_VARARGS,
     "slerp(a, b, t, out, count) -> bool: quaternions.slerp of count pairs, with the C library's acos and sin."},
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
    "Compiled kernels: BVH numbers, forward kinematics, the PNG rasteriser (optional; see _kernels.c).", -1, methods,
};

PyMODINIT_FUNC PyInit__kernels(void) { return PyModule_Create(&module); }
