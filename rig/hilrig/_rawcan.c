/* Batched frame I/O for the lockstep exchange on a raw SocketCAN socket (hilrig.transport).
 *
 * Why C: a lockstep cycle moves about ten frames (two or three RPDOs and SYNC out, every due
 * TPDO back). Through Python's socket methods each frame is a system call plus a method call,
 * an exception check, a struct unpack and a slice, which in the qemu micro-VM's software
 * emulation costs more than the firmware's whole turnaround. Here a cycle's frames go out in
 * one sendmmsg(2) and come back in as few recvmmsg(2) calls as their arrival allows, and the
 * (can_id, data) tuples are built without interpreter work per frame.
 *
 * Protocol rules stay in Python: this module only moves struct can_frame records (16 bytes:
 * can_id in host byte order with its EFF/RTR/ERR flags, length, 3 pad bytes, 8 data bytes).
 * It works on any datagram socket carrying such records; the unit tests use a Unix socketpair.
 *
 * Waiting: recv_frames(fd, True) blocks for the first frame as long as the socket's own
 * receive timeout (SO_RCVTIMEO, set by RawCanLink) allows and then takes what is queued
 * without waiting (MSG_WAITFORONE); recv_frames(fd, False) never waits. The interpreter lock
 * is released while the kernel works, so the tracer's sender thread runs meanwhile.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>

#include <errno.h>  /* sendmmsg/recvmmsg need _GNU_SOURCE, which pyconfig.h defines */
#include <stdint.h>
#include <string.h>
#include <sys/socket.h>
#include <sys/uio.h>

#define FRAME_SIZE 16
#define FRAME_DATA_OFFSET 8
#define MAX_DATA 8
/* Frames taken per recvmmsg: more than a cycle's TPDOs; a longer queue takes another call. */
#define BATCH 32

static int is_would_block(int error) { return error == EAGAIN || error == EWOULDBLOCK; }

/* send_frames(fd, frames): every record of `frames` (a multiple of 16 bytes) in order. */
static PyObject *send_frames(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "send_frames(fd, frames) takes 2 arguments");
        return NULL;
    }
    int fd = PyObject_AsFileDescriptor(args[0]);
    if (fd < 0) return NULL;
    Py_buffer view;
    if (PyObject_GetBuffer(args[1], &view, PyBUF_SIMPLE) < 0) return NULL;
    if (view.len % FRAME_SIZE != 0) {
        PyBuffer_Release(&view);
        PyErr_Format(PyExc_ValueError, "send_frames: %zd bytes are no whole number of %d-byte frames",
                     view.len, FRAME_SIZE);
        return NULL;
    }
    Py_ssize_t count = view.len / FRAME_SIZE;
    Py_ssize_t done = 0;
    struct mmsghdr messages[BATCH];
    struct iovec vectors[BATCH];
    while (done < count) {
        unsigned int chunk = (unsigned int)(count - done < BATCH ? count - done : BATCH);
        memset(messages, 0, sizeof(struct mmsghdr) * chunk);
        for (unsigned int i = 0; i < chunk; ++i) {
            vectors[i].iov_base = (char *)view.buf + (done + i) * FRAME_SIZE;
            vectors[i].iov_len = FRAME_SIZE;
            messages[i].msg_hdr.msg_iov = &vectors[i];
            messages[i].msg_hdr.msg_iovlen = 1;
        }
        int sent;
        Py_BEGIN_ALLOW_THREADS
        sent = sendmmsg(fd, messages, chunk, 0);
        Py_END_ALLOW_THREADS
        if (sent < 0) {
            if (errno == EINTR) {
                if (PyErr_CheckSignals() < 0) break;
                continue;
            }
            PyErr_SetFromErrno(PyExc_OSError);
            break;
        }
        done += sent;
    }
    PyBuffer_Release(&view);
    if (PyErr_Occurred()) return NULL;
    Py_RETURN_NONE;
}

/* recv_frames(fd, wait) -> list of (can_id, data): what is queued (see the module comment). */
static PyObject *recv_frames(PyObject *module, PyObject *const *args, Py_ssize_t nargs) {
    (void)module;
    if (nargs != 2) {
        PyErr_SetString(PyExc_TypeError, "recv_frames(fd, wait) takes 2 arguments");
        return NULL;
    }
    int fd = PyObject_AsFileDescriptor(args[0]);
    if (fd < 0) return NULL;
    int wait = PyObject_IsTrue(args[1]);
    if (wait < 0) return NULL;

    PyObject *frames = PyList_New(0);
    if (frames == NULL) return NULL;
    unsigned char buffer[BATCH][FRAME_SIZE];
    struct mmsghdr messages[BATCH];
    struct iovec vectors[BATCH];
    int flags = wait ? MSG_WAITFORONE : MSG_DONTWAIT;
    for (;;) {
        memset(messages, 0, sizeof(messages));
        for (int i = 0; i < BATCH; ++i) {
            vectors[i].iov_base = buffer[i];
            vectors[i].iov_len = FRAME_SIZE;
            messages[i].msg_hdr.msg_iov = &vectors[i];
            messages[i].msg_hdr.msg_iovlen = 1;
        }
        int got;
        Py_BEGIN_ALLOW_THREADS
        got = recvmmsg(fd, messages, BATCH, flags, NULL);
        Py_END_ALLOW_THREADS
        if (got < 0) {
            if (errno == EINTR) {  /* a signal: run its handler (Ctrl-C raises), then go on */
                if (PyErr_CheckSignals() < 0) goto fail;
                continue;
            }
            if (is_would_block(errno)) break;  /* nothing (more) queued, or the timeout ran out */
            PyErr_SetFromErrno(PyExc_OSError);
            goto fail;
        }
        for (int i = 0; i < got; ++i) {
            if (messages[i].msg_len < FRAME_DATA_OFFSET) continue;  /* no can_frame: ignore */
            uint32_t can_id;
            memcpy(&can_id, buffer[i], sizeof can_id);
            unsigned int length = buffer[i][4];
            if (length > MAX_DATA) length = MAX_DATA;
            if (FRAME_DATA_OFFSET + length > messages[i].msg_len)
                length = messages[i].msg_len - FRAME_DATA_OFFSET;
            PyObject *item = Py_BuildValue("(ky#)", (unsigned long)can_id,
                                           (const char *)buffer[i] + FRAME_DATA_OFFSET,
                                           (Py_ssize_t)length);
            if (item == NULL) goto fail;
            int appended = PyList_Append(frames, item);
            Py_DECREF(item);
            if (appended < 0) goto fail;
        }
        if (got < BATCH) break;  /* the queue is empty now */
        flags = MSG_DONTWAIT;    /* a full batch: take the rest without waiting */
    }
    return frames;
fail:
    Py_DECREF(frames);
    return NULL;
}

static PyMethodDef methods[] = {
    {"send_frames", (PyCFunction)(void (*)(void))send_frames, METH_FASTCALL,
     "send_frames(fd, frames): send every 16-byte can_frame record of `frames`, in order."},
    {"recv_frames", (PyCFunction)(void (*)(void))recv_frames, METH_FASTCALL,
     "recv_frames(fd, wait) -> [(can_id, data), ...]: the queued frames; with wait, first "
     "block for one as long as the socket's SO_RCVTIMEO allows ([] when none came)."},
    {NULL, NULL, 0, NULL},
};

static PyModuleDef_Slot slots[] = {
#if PY_VERSION_HEX >= 0x030C0000
    {Py_mod_multiple_interpreters, Py_MOD_PER_INTERPRETER_GIL_SUPPORTED},
#endif
    {0, NULL},
};

static struct PyModuleDef module_def = {
    PyModuleDef_HEAD_INIT,
    .m_name = "hilrig._rawcan",
    .m_doc = "Batched struct can_frame I/O for hilrig.transport (see _rawcan.c).",
    .m_size = 0,
    .m_methods = methods,
    .m_slots = slots,
};

PyMODINIT_FUNC PyInit__rawcan(void) { return PyModuleDef_Init(&module_def); }
