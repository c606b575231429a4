/* hilrig.wire._wire: the per-cycle PDO exchange on a raw SocketCAN socket, without a Python call per
 * frame (used through hilrig.wire.transport only; every rule about which frame is due, late or
 * malformed stays in Python, in hilrig.engine.lockstep).
 *
 * In the software-emulated micro-VM a Python bytecode costs many times its native time while a
 * system call costs far less, so the Python wrapper and loop around each recv() (eight a cycle)
 * made up a large share of a lockstep cycle. Here a cycle's frames go out in one call, and the
 * due TPDOs of the usual length are received and decoded in one call; any other frame goes back
 * to Python at once, in arrival order, for the rules there.
 *
 *   send_frames(fd, frames)                      every 16-byte struct can_frame of `frames`
 *   exchange(fd, out, due, decoders, got, spin_s[, cycle])
 *                                                send `out`, then receive (see exchange_doc)
 *   append_rows(frames, rows, cycle)             the RPDO frames a cycle sent into their rows
 *   receive_stamped(fd, max_frames)              what is queued, with the kernel's receive times
 *
 * A decoder may carry its PDO's history rows (two bytearrays: the cycles as native int64, the
 * payloads back to back): each TPDO it decodes is then also appended there, tagged with
 * `cycle`, so the rig's per-cycle bookkeeping of every TPDO needs no Python object either;
 * `append_rows` files the RPDO frames a cycle sent the same way (it touches no socket: the
 * lockstep driver calls it on any link).
 *
 * The socket is blocking with the kernel's receive timeout (SO_RCVTIMEO, set by the caller): a
 * wait is a short look without sleeping (`receive`), then one recv() that returns EAGAIN when
 * the slice passed. The GIL is released around
 * every system call (canopen's receive thread and the tracer's sender run meanwhile), and a
 * signal (Ctrl-C) during a wait raises as Python's own socket calls do.
 */
#define _GNU_SOURCE /* recvmmsg */
#define PY_SSIZE_T_CLEAN
#define Py_LIMITED_API 0x030B0000 /* the stable ABI of CPython 3.11+: one wheel for them all (abi3) */
#include <Python.h>

#include <errno.h>
#include <sched.h>
#include <stdint.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <time.h>

#define FRAME_SIZE 16 /* struct can_frame: can_id (4), len (1), pad (3), data (8) */

/* A received struct can_frame's can_id, flags included, and its data length (at most 8). */
static uint32_t frame_can_id(const unsigned char *frame) {
    uint32_t can_id;
    memcpy(&can_id, frame, sizeof can_id);
    return can_id;
}

static Py_ssize_t frame_data_length(const unsigned char *frame) {
    return frame[4] <= 8 ? frame[4] : 8;
}

static int fd_argument(PyObject *object) {
    long fd = PyLong_AsLong(object);
    if (fd == -1 && PyErr_Occurred()) {
        return -1;
    }
    if (fd < 0 || fd > INT32_MAX) {
        PyErr_Format(PyExc_ValueError, "expected a file descriptor, got %ld", fd);
        return -1;
    }
    return (int)fd;
}

static int send_all(int fd, const char *frames, Py_ssize_t size) {
    for (Py_ssize_t offset = 0; offset < size; offset += FRAME_SIZE) {
        ssize_t sent;
        int error;
        do {
            Py_BEGIN_ALLOW_THREADS
            sent = send(fd, frames + offset, FRAME_SIZE, 0);
            error = errno;
            Py_END_ALLOW_THREADS
            if (sent < 0 && error == EINTR && PyErr_CheckSignals() < 0) {
                return -1;
            }
        } while (sent < 0 && error == EINTR);
        if (sent < 0) {
            errno = error;
            PyErr_SetFromErrno(PyExc_OSError);
            return -1;
        }
    }
    return 0;
}

/* The bytes of `object` (any bytes-like) into `frames` when they are whole 16-byte frames; 0, or
 * -1 with an error set (a ValueError naming `what` when the length is not whole frames) and
 * nothing to release. */
static int get_frames(PyObject *object, Py_buffer *frames, const char *what) {
    if (PyObject_GetBuffer(object, frames, PyBUF_SIMPLE) < 0) {
        return -1;
    }
    if (frames->len % FRAME_SIZE != 0) {
        PyErr_Format(PyExc_ValueError, "%s: expected whole 16-byte CAN frames, got %zd bytes", what,
                     frames->len);
        PyBuffer_Release(frames);
        return -1;
    }
    return 0;
}

/* Send the frames of `object` (any bytes-like of whole 16-byte frames) on `fd`; 0, or -1 with an
 * error set (`get_frames`, or the send's). */
static int send_object(int fd, PyObject *object, const char *what) {
    Py_buffer frames;
    if (get_frames(object, &frames, what) < 0) {
        return -1;
    }
    int status = frames.len > 0 ? send_all(fd, frames.buf, frames.len) : 0;
    PyBuffer_Release(&frames);
    return status;
}

PyDoc_STRVAR(send_frames_doc,
             "send_frames(fd, frames, /)\n--\n\n"
             "Send every 16-byte struct can_frame of `frames` on the raw CAN socket `fd`, in order.");

static PyObject *send_frames(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "send_frames(fd, frames) takes 2 arguments");
        return NULL;
    }
    int fd = fd_argument(args[0]);
    if (fd < 0) {
        return NULL;
    }
    if (send_object(fd, args[1], "send_frames") < 0) {
        return NULL;
    }
    Py_RETURN_NONE;
}

/* How many COB-IDs of `due` are not keys of `got` yet; -1 on error. */
static Py_ssize_t count_missing(PyObject *due, PyObject *got) {
    Py_ssize_t missing = 0;
    PyObject *iterator = PyObject_GetIter(due);
    if (iterator == NULL) {
        return -1;
    }
    PyObject *cob_id;
    while ((cob_id = PyIter_Next(iterator)) != NULL) {
        int present = PyDict_Contains(got, cob_id);
        Py_DECREF(cob_id);
        if (present < 0) {
            Py_DECREF(iterator);
            return -1;
        }
        missing += !present;
    }
    Py_DECREF(iterator);
    return PyErr_Occurred() ? -1 : missing;
}

static int64_t monotonic_ns(void) {
    struct timespec now;
    clock_gettime(CLOCK_MONOTONIC, &now);
    return (int64_t)now.tv_sec * 1000000000 + now.tv_nsec;
}

/* Append `size` bytes to a bytearray, its buffer doubling. A bytearray alone grows by an eighth,
 * so a history's stores (rows, arrivals: one append per frame, kept for the whole run) would be
 * copied whole every few hundred cycles: eight bytes copied per byte kept. The limited API does
 * not show the allocation, so on crossing a power of two the buffer is first resized to twice
 * the next one, then back: CPython keeps a buffer that shrinks by less than half, and the
 * appends up to that power of two need no copy. Elsewhere it is as correct, only not faster. */
static Py_ALWAYS_INLINE inline int append_bytes(PyObject *array, const void *bytes, Py_ssize_t size) {
    Py_ssize_t before = PyByteArray_Size(array), after = before + size;
    if (after >= 256 && (after ^ before) > before) { /* after's top bit is above before's */
        Py_ssize_t power = 256;
        while (power <= after / 2) power <<= 1; /* the power of two crossed */
        if (PyByteArray_Resize(array, 2 * power) < 0) {
            return -1;
        }
    }
    if (PyByteArray_Resize(array, after) < 0) {
        return -1;
    }
    memcpy(PyByteArray_AsString(array) + before, bytes, (size_t)size);
    return 0;
}

/* The values of a due TPDO of the usual length (a new reference), or NULL without an error set
 * when the frame is not that (then it goes back to Python), or NULL with an error set. */
static PyObject *usual_values(PyObject *cob_id, const unsigned char *data, Py_ssize_t length, PyObject *due,
                              PyObject *decoders, PyObject *got, const int64_t *cycle, int64_t received_at) {
    int wanted = PySet_Contains(due, cob_id);
    if (wanted <= 0) {
        return NULL;
    }
    wanted = PyDict_Contains(got, cob_id);
    if (wanted != 0) {
        return NULL; /* twice (or an error) */
    }
    PyObject *decoder = PyDict_GetItemWithError(decoders, cob_id); /* borrowed */
    if (decoder == NULL) {
        return NULL;
    }
    Py_ssize_t items = PyTuple_Check(decoder) ? PyTuple_Size(decoder) : 0;
    if (items != 2 && items != 4 && items != 5) {
        PyErr_SetString(PyExc_TypeError, "exchange: a decoder is a (length, unpack), (length, unpack, cycles, "
                                         "payloads) or (length, unpack, cycles, payloads, arrivals) tuple");
        return NULL;
    }
    Py_ssize_t expected = PyLong_AsSsize_t(PyTuple_GetItem(decoder, 0));
    if (expected == -1 && PyErr_Occurred()) {
        return NULL;
    }
    if (expected != length) {
        return NULL;
    }
    PyObject *payload = PyBytes_FromStringAndSize((const char *)data, length);
    if (payload == NULL) {
        return NULL;
    }
    PyObject *values = PyObject_CallFunctionObjArgs(PyTuple_GetItem(decoder, 1), payload, NULL);
    Py_DECREF(payload);
    if (values == NULL || items == 2) {
        return values;
    }
    PyObject *cycles = PyTuple_GetItem(decoder, 2), *rows = PyTuple_GetItem(decoder, 3);
    if (cycle == NULL || !PyByteArray_CheckExact(cycles) || !PyByteArray_CheckExact(rows)) {
        Py_DECREF(values);
        PyErr_SetString(PyExc_TypeError, "exchange: rows need their cycle, and bytearrays to go in");
        return NULL;
    }
    /* The payload first, then the cycle: a reader counts rows by their cycles, so a row it
     * counts always has its payload (the tracer reads from another thread). */
    if (append_bytes(rows, data, length) < 0 || append_bytes(cycles, cycle, sizeof *cycle) < 0) {
        Py_DECREF(values);
        return NULL;
    }
    if (items == 5) { /* when it came: (cycle, CLOCK_MONOTONIC ns), two native int64 */
        PyObject *arrivals = PyTuple_GetItem(decoder, 4);
        int64_t arrival[2] = {*cycle, received_at};
        if (!PyByteArray_CheckExact(arrivals) || append_bytes(arrivals, arrival, sizeof arrival) < 0) {
            Py_DECREF(values);
            if (!PyErr_Occurred()) {
                PyErr_SetString(PyExc_TypeError, "exchange: arrivals go in a bytearray");
            }
            return NULL;
        }
    }
    return values;
}

/* Room for the kernel's receive time of one frame, of either kind. */
typedef union {
    char space[CMSG_SPACE(sizeof(struct timespec))];
    struct cmsghdr align;
} StampControl;

/* The kernel's receive time of a received message in CLOCK_REALTIME nanoseconds: its
 * SCM_TIMESTAMPNS (SO_TIMESTAMPNS, which RawCanLink sets) or SCM_TIMESTAMP (SO_TIMESTAMP,
 * `enable_timestamps`); -1 when it carries neither. */
static int64_t kernel_stamp_ns(struct msghdr *message) {
    int64_t stamp = -1;
    for (struct cmsghdr *c = CMSG_FIRSTHDR(message); c != NULL; c = CMSG_NXTHDR(message, c)) {
        if (c->cmsg_level != SOL_SOCKET) {
            continue;
        }
        if (c->cmsg_type == SCM_TIMESTAMPNS) {
            struct timespec when;
            memcpy(&when, CMSG_DATA(c), sizeof when);
            stamp = (int64_t)when.tv_sec * 1000000000 + when.tv_nsec;
        } else if (c->cmsg_type == SCM_TIMESTAMP) {
            struct timeval when;
            memcpy(&when, CMSG_DATA(c), sizeof when);
            stamp = (int64_t)when.tv_sec * 1000000000 + (int64_t)when.tv_usec * 1000;
        }
    }
    return stamp;
}

/* One frame into `frame` (recv's flags), and its `kernel_stamp_ns` into `kernel_ns` (-1: none).
 * Returns recvmsg()'s result. */
static ssize_t receive_frame(int fd, unsigned char *frame, int flags, int64_t *kernel_ns) {
    struct iovec vector = {frame, FRAME_SIZE};
    StampControl control;
    struct msghdr message;
    memset(&message, 0, sizeof message);
    message.msg_iov = &vector;
    message.msg_iovlen = 1;
    message.msg_control = control.space;
    message.msg_controllen = sizeof control.space;
    ssize_t received = recvmsg(fd, &message, flags);
    *kernel_ns = received < 0 ? -1 : kernel_stamp_ns(&message);
    return received;
}

/* CLOCK_REALTIME minus CLOCK_MONOTONIC, read again once the kernel's receive times have moved on
 * by OFFSET_REFRESH_NS since the last reading (an NTP slew moves it by microseconds a second at
 * most). Touched with the GIL held only. */
#define OFFSET_REFRESH_NS 100000000 /* 0.1 s */
static int64_t realtime_offset_ns;
static int64_t offset_read_at_ns; /* CLOCK_REALTIME of that reading (0: none yet) */

/* When a frame the kernel received at `kernel_ns` (CLOCK_REALTIME, -1: not known) came, on the
 * CLOCK_MONOTONIC nanoseconds of the arrivals: the kernel's time, not a clock read a frame (in
 * the bus stage's VM every clock read is a system call the host traps, some 30 us). */
static int64_t arrival_ns(int64_t kernel_ns) {
    if (kernel_ns < 0) {
        return monotonic_ns();
    }
    if (kernel_ns - offset_read_at_ns > OFFSET_REFRESH_NS || kernel_ns < offset_read_at_ns) {
        /* Between two monotonic reads: a read is slow in the VM, which would skew it. */
        struct timespec real;
        int64_t before = monotonic_ns();
        clock_gettime(CLOCK_REALTIME, &real);
        int64_t after = monotonic_ns();
        offset_read_at_ns = (int64_t)real.tv_sec * 1000000000 + real.tv_nsec;
        realtime_offset_ns = offset_read_at_ns - (before + (after - before) / 2);
    }
    return kernel_ns - realtime_offset_ns;
}

/* How long a wait on each socket looks for a frame before it sleeps, by file descriptor; adapted
 * as it goes (see `receive`). -1: not used yet. Only touched by the thread using that socket. */
#define LOOK_SLOTS 4096
static int64_t look_ns[LOOK_SLOTS];
static const int64_t kLookStepNs = 20000; /* 20 us: what a look that paid grows by */

/* One frame into `frame`: when `wait`, look for one without sleeping (yielding the CPU to anything
 * else runnable) for up to the socket's current look time, then block up to the socket's receive
 * timeout; otherwise only take what is queued. Returns recv()'s result, its errno in `error`.
 *
 * Why look before sleeping: a cycle's TPDOs come some microseconds apart, and the exchange takes
 * each in far less. Blocking between them puts the rig's CPU to sleep and has the next frame
 * wake it, which in the software-emulated VM costs more than the whole frame (`make bench`'s
 * exchange-alone row shows what looking is worth).
 *
 * Why adapt: looking burns the CPU the node (and, on a shared machine, everything else) may need
 * when the node is slow to answer. So the look time halves each time a look finds nothing, and
 * grows (doubled plus 20 us, up to `max_look_ns`) each time a look, or a sleep shorter than
 * `max_look_ns`, found the frame: a node answering within it is looked for, a loaded one is
 * slept on. Called without the GIL. */
static ssize_t receive(int fd, unsigned char *frame, int wait, int64_t max_look_ns, int *error, int64_t *kernel_ns) {
    ssize_t received = receive_frame(fd, frame, MSG_DONTWAIT, kernel_ns);
    *error = errno;
    if (received >= 0 || !wait || (*error != EAGAIN && *error != EWOULDBLOCK)) {
        return received;
    }
    int64_t *look = fd < LOOK_SLOTS ? &look_ns[fd] : NULL;
    int64_t budget = look == NULL ? 0 : (*look < 0 || *look > max_look_ns ? max_look_ns : *look);
    int64_t started = monotonic_ns();
    if (budget > 0) {
        do {
            sched_yield();
            received = receive_frame(fd, frame, MSG_DONTWAIT, kernel_ns);
            *error = errno;
            if (received >= 0 || (*error != EAGAIN && *error != EWOULDBLOCK)) {
                if (received >= 0) {
                    budget = 2 * budget + kLookStepNs;
                    *look = budget < max_look_ns ? budget : max_look_ns;
                }
                return received;
            }
        } while (monotonic_ns() - started < budget);
        *look = budget / 2 < kLookStepNs / 2 ? 0 : budget / 2;
    }
    received = receive_frame(fd, frame, 0, kernel_ns);
    *error = errno;
    if (look != NULL && received >= 0 && max_look_ns > 0 && *look == 0 &&
        monotonic_ns() - started < max_look_ns) {
        *look = kLookStepNs; /* the frame came soon after all: look again next time */
    }
    return received;
}

PyDoc_STRVAR(exchange_doc,
             "exchange(fd, out, due, decoders, got, spin_s, cycle=None, /)\n--\n\n"
             "Send the frames of `out` (whole 16-byte struct can_frames, may be empty), then\n"
             "receive on `fd`. A frame whose COB-ID is in `due` (a frozenset), is not yet a key\n"
             "of `got` and has the length of its decoder (`decoders[cob_id] = (length,\n"
             "unpack)`) is decoded into `got[cob_id] = unpack(data)`; a decoder `(length, unpack,\n"
             "cycles, payloads)` also appends `cycle` (a native int64) and the data to those two\n"
             "bytearrays; `(length, unpack, cycles, payloads, arrivals)` also the cycle and the\n"
             "CLOCK_MONOTONIC nanoseconds it was received at (two native int64) to `arrivals`:\n"
             "the kernel's receive time where the socket has SO_TIMESTAMPNS (or SO_TIMESTAMP) on.\n"
             "Returns:\n"
             "  (cob_id, data)  the first frame that is anything else, at once (Python judges it);\n"
             "  False           the socket's receive timeout passed with a due COB-ID missing;\n"
             "  None            every due COB-ID is in `got` and nothing more is queued.\n"
             "While a due COB-ID is missing a receive looks for a frame without sleeping for up to\n"
             "`spin_s` (less while looking does not pay on this socket), then waits (up to\n"
             "SO_RCVTIMEO); after that it only takes what is queued.");

static PyObject *exchange(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 6 && nargs != 7) {
        PyErr_SetString(PyExc_TypeError,
                        "exchange(fd, out, due, decoders, got, spin_s, cycle=None) takes 6 or 7 arguments");
        return NULL;
    }
    int64_t cycle_number = 0;
    const int64_t *cycle = NULL;
    if (nargs == 7 && args[6] != Py_None) {
        cycle_number = PyLong_AsLongLong(args[6]);
        if (cycle_number == -1 && PyErr_Occurred()) {
            return NULL;
        }
        cycle = &cycle_number;
    }
    int fd = fd_argument(args[0]);
    if (fd < 0) {
        return NULL;
    }
    double spin_s = PyFloat_AsDouble(args[5]);
    if (spin_s == -1.0 && PyErr_Occurred()) {
        return NULL;
    }
    int64_t spin_ns = spin_s > 0.0 ? (int64_t)(spin_s * 1e9) : 0;
    PyObject *due = args[2], *decoders = args[3], *got = args[4];
    if (!PyAnySet_Check(due) || !PyDict_Check(decoders) || !PyDict_Check(got)) {
        PyErr_SetString(PyExc_TypeError, "exchange: due is a set, decoders and got are dicts");
        return NULL;
    }
    if (send_object(fd, args[1], "exchange") < 0) {
        return NULL;
    }
    Py_ssize_t missing = count_missing(due, got);
    if (missing < 0) {
        return NULL;
    }
    unsigned char frame[FRAME_SIZE];
    for (;;) {
        ssize_t received;
        int error;
        int64_t kernel_ns;
        Py_BEGIN_ALLOW_THREADS
        received = receive(fd, frame, missing > 0, spin_ns, &error, &kernel_ns);
        Py_END_ALLOW_THREADS
        if (received < 0) {
            if (error == EINTR) {
                if (PyErr_CheckSignals() < 0) {
                    return NULL;
                }
                continue;
            }
            if (error == EAGAIN || error == EWOULDBLOCK) {
                if (missing > 0) {
                    Py_RETURN_FALSE;
                }
                Py_RETURN_NONE;
            }
            errno = error;
            return PyErr_SetFromErrno(PyExc_OSError);
        }
        if (received < 8) {
            continue; /* not a CAN frame; a raw CAN socket never delivers one */
        }
        Py_ssize_t length = frame_data_length(frame);
        PyObject *cob_id = PyLong_FromUnsignedLong(frame_can_id(frame));
        if (cob_id == NULL) {
            return NULL;
        }
        PyObject *values = usual_values(cob_id, frame + 8, length, due, decoders, got, cycle, arrival_ns(kernel_ns));
        if (values != NULL) {
            int stored = PyDict_SetItem(got, cob_id, values);
            Py_DECREF(values);
            Py_DECREF(cob_id);
            if (stored < 0) {
                return NULL;
            }
            missing -= 1;
            continue;
        }
        if (PyErr_Occurred()) {
            Py_DECREF(cob_id);
            return NULL;
        }
        PyObject *data = PyBytes_FromStringAndSize((const char *)frame + 8, length);
        if (data == NULL) {
            Py_DECREF(cob_id);
            return NULL;
        }
        PyObject *result = PyTuple_Pack(2, cob_id, data);
        Py_DECREF(cob_id);
        Py_DECREF(data);
        return result;
    }
}

PyDoc_STRVAR(append_rows_doc,
             "append_rows(frames, rows, cycle, /)\n--\n\n"
             "Append each 16-byte struct can_frame of `frames` whose COB-ID is a key of `rows`\n"
             "(COB-ID -> (cycles, payloads), two bytearrays) to those rows as cycle `cycle`'s: its\n"
             "payload (as long as the frame says), then the cycle as a native int64, as `exchange`\n"
             "appends a TPDO it decodes. Frames of other COB-IDs are left out.");

static PyObject *append_rows(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 3) {
        PyErr_SetString(PyExc_TypeError, "append_rows(frames, rows, cycle) takes 3 arguments");
        return NULL;
    }
    PyObject *rows = args[1];
    if (!PyDict_Check(rows)) {
        PyErr_SetString(PyExc_TypeError, "append_rows: rows is a dict");
        return NULL;
    }
    int64_t cycle = PyLong_AsLongLong(args[2]);
    if (cycle == -1 && PyErr_Occurred()) {
        return NULL;
    }
    Py_buffer frames;
    if (get_frames(args[0], &frames, "append_rows") < 0) {
        return NULL;
    }
    int status = 0;
    for (Py_ssize_t offset = 0; status == 0 && offset < frames.len; offset += FRAME_SIZE) {
        const unsigned char *frame = (const unsigned char *)frames.buf + offset;
        PyObject *cob_id = PyLong_FromUnsignedLong(frame_can_id(frame));
        if (cob_id == NULL) {
            status = -1;
            break;
        }
        PyObject *store = PyDict_GetItemWithError(rows, cob_id); /* borrowed */
        Py_DECREF(cob_id);
        if (store == NULL) {
            status = PyErr_Occurred() ? -1 : 0;
            continue;
        }
        if (!PyTuple_Check(store) || PyTuple_Size(store) != 2 ||
            !PyByteArray_CheckExact(PyTuple_GetItem(store, 0)) ||
            !PyByteArray_CheckExact(PyTuple_GetItem(store, 1))) {
            PyErr_SetString(PyExc_TypeError, "append_rows: a row store is a (cycles, payloads) tuple of bytearrays");
            status = -1;
            break;
        }
        Py_ssize_t length = frame_data_length(frame);
        /* The payload first, then the cycle, as `exchange` appends (a reader counts cycles). */
        if (append_bytes(PyTuple_GetItem(store, 1), frame + 8, length) < 0 ||
            append_bytes(PyTuple_GetItem(store, 0), &cycle, sizeof cycle) < 0) {
            status = -1;
        }
    }
    PyBuffer_Release(&frames);
    if (status < 0) {
        return NULL;
    }
    Py_RETURN_NONE;
}

#define STAMPED_BATCH 64 /* frames per recvmmsg */

PyDoc_STRVAR(receive_stamped_doc,
             "receive_stamped(fd, max_frames, /)\n--\n\n"
             "Up to `max_frames` frames already queued on the raw CAN socket `fd` (SO_TIMESTAMP or\n"
             "SO_TIMESTAMPNS on), "
             "without waiting: a list of (raw can_id with its EFF/RTR/ERR flags, data, kernel\n"
             "receive time [s since the epoch]), oldest first; empty when nothing is queued. Taken\n"
             "STAMPED_BATCH at a time (recvmmsg): a bus recorder's work per frame is then one tuple.");

static PyObject *receive_stamped(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "receive_stamped(fd, max_frames) takes 2 arguments");
        return NULL;
    }
    int fd = fd_argument(args[0]);
    if (fd < 0) {
        return NULL;
    }
    Py_ssize_t wanted = PyLong_AsSsize_t(args[1]);
    if (wanted == -1 && PyErr_Occurred()) {
        return NULL;
    }
    PyObject *received = PyList_New(0);
    if (received == NULL) {
        return NULL;
    }
    unsigned char frames[STAMPED_BATCH][FRAME_SIZE];
    StampControl control[STAMPED_BATCH];
    struct iovec vectors[STAMPED_BATCH];
    struct mmsghdr messages[STAMPED_BATCH];
    while (PyList_Size(received) < wanted) {
        Py_ssize_t room = wanted - PyList_Size(received);
        unsigned int batch = room < STAMPED_BATCH ? (unsigned int)room : STAMPED_BATCH;
        memset(messages, 0, sizeof messages);
        for (unsigned int i = 0; i < batch; ++i) {
            vectors[i].iov_base = frames[i];
            vectors[i].iov_len = FRAME_SIZE;
            messages[i].msg_hdr.msg_iov = &vectors[i];
            messages[i].msg_hdr.msg_iovlen = 1;
            messages[i].msg_hdr.msg_control = control[i].space;
            messages[i].msg_hdr.msg_controllen = sizeof control[i].space;
        }
        int count;
        int error;
        Py_BEGIN_ALLOW_THREADS
        count = recvmmsg(fd, messages, batch, MSG_DONTWAIT, NULL);
        error = errno;
        Py_END_ALLOW_THREADS
        if (count < 0) {
            if (error == EINTR) {
                if (PyErr_CheckSignals() < 0) {
                    Py_DECREF(received);
                    return NULL;
                }
                continue;
            }
            if (error == EAGAIN || error == EWOULDBLOCK) {
                break;
            }
            Py_DECREF(received);
            errno = error;
            return PyErr_SetFromErrno(PyExc_OSError);
        }
        for (int i = 0; i < count; ++i) {
            int64_t stamp_ns = kernel_stamp_ns(&messages[i].msg_hdr);
            /* Seconds and their fraction apart: for a microsecond stamp this is the same double
             * as tv_sec + tv_usec / 1e6. */
            double stamp = stamp_ns < 0 ? 0.0
                                        : (double)(stamp_ns / 1000000000) + (double)(stamp_ns % 1000000000) / 1e9;
            PyObject *entry = Py_BuildValue("(ky#d)", (unsigned long)frame_can_id(frames[i]),
                                            (const char *)frames[i] + 8, frame_data_length(frames[i]), stamp);
            if (entry == NULL || PyList_Append(received, entry) < 0) {
                Py_XDECREF(entry);
                Py_DECREF(received);
                return NULL;
            }
            Py_DECREF(entry);
        }
        if ((unsigned int)count < batch) {
            break; /* the queue is empty */
        }
    }
    return received;
}

static PyMethodDef methods[] = {
    {"send_frames", (PyCFunction)(void (*)(void))send_frames, METH_FASTCALL, send_frames_doc},
    {"exchange", (PyCFunction)(void (*)(void))exchange, METH_FASTCALL, exchange_doc},
    {"append_rows", (PyCFunction)(void (*)(void))append_rows, METH_FASTCALL, append_rows_doc},
    {"receive_stamped", (PyCFunction)(void (*)(void))receive_stamped, METH_FASTCALL, receive_stamped_doc},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef wire_module = {
    PyModuleDef_HEAD_INIT,
    "hilrig.wire._wire",
    "The per-cycle PDO exchange on a raw SocketCAN socket (hilrig.wire.transport's fast path).",
    -1,
    methods,
    NULL,
    NULL,
    NULL,
    NULL,
};

PyMODINIT_FUNC PyInit__wire(void) {
    for (int fd = 0; fd < LOOK_SLOTS; ++fd) {
        look_ns[fd] = -1;
    }
    PyObject *module = PyModule_Create(&wire_module);
    if (module != NULL && PyModule_AddIntConstant(module, "FRAME_SIZE", FRAME_SIZE) < 0) {
        Py_DECREF(module);
        return NULL;
    }
    return module;
}
