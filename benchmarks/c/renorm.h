/*
 * The renormalisation constants both C twins of warpratchet.kernels.advance_map need, passed by
 * throughput.py from warpratchet.kernels so that the C and the kernel can never disagree.
 */
#ifndef RATCHET_RENORM_H
#define RATCHET_RENORM_H

#ifndef RENORM_THRESHOLD
#error "compile with -DRENORM_THRESHOLD=<warpratchet.kernels.RENORM_THRESHOLD>"
#endif
#ifndef RENORM_CHECK_EVERY
#error "compile with -DRENORM_CHECK_EVERY=<warpratchet.kernels.RENORM_CHECK_EVERY>"
#endif

#endif
