# distutils: sources = src/switchest/engine/c/gpb.c
"""Binding of the banks of mode-matched filters: the IMM's and GPB1's kernel
(engine/c/bank.c), :func:`filter_bank`, behind :func:`switchest.engine.imm.imm_run`,
:func:`switchest.engine.imm.imm_step` and :class:`switchest.engine.imm.Bank`; GPB2's
(engine/c/gpb.c), :func:`gpb2_bank`, behind :func:`switchest.engine.gpb.gpb2_run` and
:func:`switchest.engine.gpb.gpb2_step`."""
cimport numpy as cnp
from ._common cimport (fptr, iptr, se_int, se_bank_out, bank_call, bank_arguments,
                      no_memory, start_binding)
start_binding()

cdef extern from "bank.h":
    se_int se_filter_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                          se_int trans_N, se_int trans_K, se_int out_N, se_int out_K,
                          se_int transition_N, const double *y,
                          const double *u, const double *F, const double *G,
                          const double *Qd, const se_int *trans, const double *C,
                          const double *R, const se_int *out_index, const double *transition,
                          const double *log_transition, const double *x_init,
                          const double *P_init, const double *log_prob_init,
                          se_int interaction, int sample_timing, int predict_first,
                          double gate, se_int lanes, const se_bank_out *out,
                          double *report) nogil

def filter_bank(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd,
                cnp.ndarray trans, cnp.ndarray C, cnp.ndarray R, cnp.ndarray out_index,
                cnp.ndarray transition, cnp.ndarray log_transition, cnp.ndarray x_init,
                cnp.ndarray P_init, cnp.ndarray log_prob_init, se_int interaction,
                bint sample_timing, bint predict_first, double gate, se_int lanes, *outputs):
    """Run ``se_filter_bank`` on arrays checked and shaped by the caller
    (:func:`switchest.engine.imm._bank`; the shapes are in engine/c/bank.h), the outputs and
    the report after the inputs (``outputs``, in the order of ``_common.bank_arguments``):
    writes them in place, returns the status (``MemoryError`` for ``SE_NO_MEMORY``)."""
    cdef bank_call c = bank_arguments(lanes, y, u, x_init, outputs)
    cdef se_int status
    with nogil:
        status = se_filter_bank(
            c.n, c.m, c.l, c.L, c.N, c.K, trans.shape[0], trans.shape[1], out_index.shape[0],
            out_index.shape[1], transition.shape[0], fptr(y), fptr(u), fptr(F), fptr(G),
            fptr(Qd), iptr(trans), fptr(C), fptr(R), iptr(out_index), fptr(transition),
            fptr(log_transition), fptr(x_init), fptr(P_init), fptr(log_prob_init), interaction,
            sample_timing, predict_first, gate, lanes, &c.out, c.report)
    no_memory(status, "filter_bank")
    return status


cdef extern from "gpb.h":
    se_int se_gpb2_bank(se_int n, se_int m, se_int l, se_int L, se_int N, se_int K,
                        se_int trans_N, se_int trans_K, const double *y,
                        const double *u, const double *F, const double *G, const double *Qd,
                        const se_int *trans, const double *C, const double *R,
                        const double *log_transition, const double *x_init,
                        const double *P_init, const double *log_prob_init, int sample_timing,
                        int predict_first, double gate, se_int lanes,
                        const se_bank_out *out, double *report) nogil


def gpb2_bank(cnp.ndarray y, cnp.ndarray u, cnp.ndarray F, cnp.ndarray G, cnp.ndarray Qd,
              cnp.ndarray trans, cnp.ndarray C, cnp.ndarray R, cnp.ndarray log_transition,
              cnp.ndarray x_init, cnp.ndarray P_init, cnp.ndarray log_prob_init,
              bint sample_timing, bint predict_first, double gate, se_int lanes, *outputs):
    """Run ``se_gpb2_bank`` on arrays checked and shaped by the caller
    (:func:`switchest.engine.gpb._gpb2`; the shapes are in engine/c/gpb.h), the outputs and the
    report after the inputs (``outputs``, in the order of ``_common.bank_arguments``): writes
    them in place, returns the status (``MemoryError`` for ``SE_NO_MEMORY``)."""
    cdef bank_call c = bank_arguments(lanes, y, u, x_init, outputs)
    cdef se_int status
    with nogil:
        status = se_gpb2_bank(
            c.n, c.m, c.l, c.L, c.N, c.K, trans.shape[0], trans.shape[1], fptr(y), fptr(u),
            fptr(F), fptr(G), fptr(Qd), iptr(trans), fptr(C), fptr(R), fptr(log_transition),
            fptr(x_init), fptr(P_init), fptr(log_prob_init), sample_timing, predict_first,
            gate, lanes, &c.out, c.report)
    no_memory(status, "gpb2_bank")
    return status
