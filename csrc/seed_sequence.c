/* The state numpy.random.default_rng(entropy) starts its PCG64 generator in, without the
 * Python objects default_rng makes on the way (a SeedSequence, a BitGenerator, a lock): the
 * compiled kernel of the ToF sensor's per-reading noise generator
 * (guidedarm.systems.tof.tof_tool_sensor_math.SeededGenerator), which sets a reused
 * Generator to this state. tests/test_seed_sequence_kernel.py holds it to numpy's own
 * default_rng on many seeds (the same state, the same draws).
 *
 * The algorithms are those numpy documents for its SeedSequence (M. E. O'Neill's entropy
 * pool: four 32-bit words mixed by multiply-xorshift hashes) and PCG64 (a 128-bit linear
 * congruential state with an odd increment, seeded by two steps):
 * PcgState(entropy) -> (state_high, state_low, inc_high, inc_low)
 *   entropy: a sequence of ints >= 0 (each contributes its 32-bit words, least significant
 *   first, at least one); the four 64-bit halves of the PCG64 state and increment. */

#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <stdint.h>

#define POOL_SIZE 4
#define MAX_WORDS 64
#define INIT_A 0x43b0d7e5u
#define MULT_A 0x931e8875u
#define INIT_B 0x8b51f9ddu
#define MULT_B 0x58f38dedu
#define MIX_MULT_L 0xca01f9ddu
#define MIX_MULT_R 0x4973f715u
#define XSHIFT 16

typedef unsigned __int128 u128;

static uint32_t HashMix(uint32_t value, uint32_t *hash) {
    value ^= *hash;
    *hash *= MULT_A;
    value *= *hash;
    value ^= value >> XSHIFT;
    return value;
}

static uint32_t Mix(uint32_t x, uint32_t y) {
    uint32_t result = MIX_MULT_L * x - MIX_MULT_R * y;
    result ^= result >> XSHIFT;
    return result;
}

/* The pool of `count` entropy words. */
static void MixEntropy(const uint32_t *entropy, int count, uint32_t *pool) {
    uint32_t hash = INIT_A;
    for (int i = 0; i < POOL_SIZE; ++i) pool[i] = HashMix(i < count ? entropy[i] : 0, &hash);
    for (int src = 0; src < POOL_SIZE; ++src)
        for (int dst = 0; dst < POOL_SIZE; ++dst)
            if (src != dst) pool[dst] = Mix(pool[dst], HashMix(pool[src], &hash));
    for (int src = POOL_SIZE; src < count; ++src)
        for (int dst = 0; dst < POOL_SIZE; ++dst)
            pool[dst] = Mix(pool[dst], HashMix(entropy[src], &hash));
}

/* The pool's first 2 n 32-bit output words as n 64-bit words (the lower word first). */
static void GenerateState(const uint32_t *pool, int n, uint64_t *out) {
    uint32_t hash = INIT_B;
    for (int i = 0; i < 2 * n; ++i) {
        uint32_t value = pool[i % POOL_SIZE];
        value ^= hash;
        hash *= MULT_B;
        value *= hash;
        value ^= value >> XSHIFT;
        if (i % 2 == 0)
            out[i / 2] = value;
        else
            out[i / 2] |= (uint64_t)value << 32;
    }
}

/* The entropy's 32-bit words; their count, or -1 with an exception. */
static int EntropyWords(PyObject *entropy, uint32_t *words) {
    PyObject *fast = PySequence_Fast(entropy, "entropy: a sequence of ints expected");
    if (!fast) return -1;
    int count = 0;
    PyObject *shift = PyLong_FromLong(32), *zero = PyLong_FromLong(0), *value = NULL;
    for (Py_ssize_t i = 0; shift && zero && i < PySequence_Fast_GET_SIZE(fast); ++i) {
        value = PyNumber_Index(PySequence_Fast_GET_ITEM(fast, i));
        if (!value) break;
        if (PyObject_RichCompareBool(value, zero, Py_LT) == 1) {
            PyErr_SetString(PyExc_ValueError, "entropy: ints >= 0 expected");
            break;
        }
        do {  /* least significant word first, at least one */
            if (count == MAX_WORDS) {
                PyErr_Format(PyExc_ValueError, "entropy: at most %d 32-bit words", MAX_WORDS);
                break;
            }
            words[count++] = (uint32_t)PyLong_AsUnsignedLongLongMask(value);
            PyObject *rest = PyNumber_Rshift(value, shift);
            Py_DECREF(value);
            value = rest;
        } while (value && PyObject_IsTrue(value) == 1);
        if (!value || PyErr_Occurred()) break;
        Py_CLEAR(value);
    }
    Py_XDECREF(value);
    Py_XDECREF(shift);
    Py_XDECREF(zero);
    Py_DECREF(fast);
    return PyErr_Occurred() ? -1 : count;
}

static PyObject *PcgState(PyObject *self, PyObject *entropy) {
    (void)self;
    uint32_t words[MAX_WORDS], pool[POOL_SIZE];
    int count = EntropyWords(entropy, words);
    if (count < 0) return NULL;
    MixEntropy(words, count, pool);
    uint64_t seed[4];
    GenerateState(pool, 4, seed);
    /* PCG64's seeding: state 0, increment 2 seq + 1, a step, the seed added, a step. */
    const u128 multiplier = ((u128)2549297995355413924ULL << 64) + 4865540595714422341ULL;
    u128 initial = ((u128)seed[0] << 64) + seed[1], sequence = ((u128)seed[2] << 64) + seed[3];
    u128 inc = (sequence << 1) | 1u, state = 0;
    state = state * multiplier + inc;
    state += initial;
    state = state * multiplier + inc;
    return Py_BuildValue("(KKKK)", (unsigned long long)(state >> 64),
                         (unsigned long long)state, (unsigned long long)(inc >> 64),
                         (unsigned long long)inc);
}

static PyMethodDef kMethods[] = {
    {"PcgState", PcgState, METH_O, "default_rng(entropy)'s PCG64 state (see the module source)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef kModule = {PyModuleDef_HEAD_INIT, "_seed_sequence",
                                     "Compiled kernel of the ToF sensor's noise seeding.", -1,
                                     kMethods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__seed_sequence(void) { return PyModule_Create(&kModule); }
