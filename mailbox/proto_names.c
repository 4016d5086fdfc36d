/* SPDX-License-Identifier: MIT */
/*
 * mailbox/proto_names.c - names of the wire format's values for logs and
 * tools (mbx_*_to_string), and how a daemon-side errno becomes the status
 * of an answer (docs/mailbox.md "Status codes").
 */
#include "mailbox/proto.h"

#include <errno.h>

/* ---- names --------------------------------------------------------------- */

const char *mbx_kind_to_string(unsigned k)
{
	switch (k) {
	case MBX_KIND_COMMAND:
		return "command";
	case MBX_KIND_RESPONSE:
		return "response";
	case MBX_KIND_EVENT:
		return "event";
	}
	return "?";
}

static const struct {
	int err;
	int status;
} status_of_errno[] = {
	{ EINVAL, MBX_E_PARAM },           /* a value the callee refuses */
	{ ENOENT, MBX_E_PARAM },           /* what it names does not exist */
	{ ERANGE, MBX_E_PARAM },           /* out of its range */
	{ ENOSPC, MBX_E_BUSY },            /* a bounded queue is full now */
	{ ENOBUFS, MBX_E_BUSY },           /* the transmit queue is full now */
	{ EBUSY, MBX_E_BUSY },             /* the resource is in use now */
	{ EAGAIN, MBX_E_STATE },           /* not in the current state */
	{ EPERM, MBX_E_STATE },            /* the state forbids it (NMT, ...) */
	{ EEXIST, MBX_E_STATE },           /* it is there already (a node added twice) */
	{ ENODEV, MBX_E_UNSUPPORTED },     /* the service is not configured */
	{ EOPNOTSUPP, MBX_E_UNSUPPORTED }, /* nor implemented */
	{ ENOMEM, MBX_E_NO_MEMORY },       /* the transfer memory budget */
	{ EMSGSIZE, MBX_E_TOO_BIG },       /* larger than a limit */
	{ E2BIG, MBX_E_TOO_BIG },
	{ ETIMEDOUT, MBX_E_NO_ANSWER }, /* the device did not answer */
	{ ESHUTDOWN, MBX_E_SHUTDOWN },  /* the line is stopping */
};

int mbx_status_of_errno(int rc)
{
	if (rc >= 0)
		return 0;
	for (size_t i = 0; i < sizeof status_of_errno / sizeof status_of_errno[0]; i++)
		if (status_of_errno[i].err == -rc)
			return status_of_errno[i].status;
	return MBX_E_INTERNAL;
}

const char *mbx_status_to_string(int status)
{
	/* by -status (MBX_OK is 0, the errors negative) */
	static const char *const names[] = {
		[-MBX_OK] = "ok",
		[-MBX_E_VERSION] = "unsupported protocol version",
		[-MBX_E_MALFORMED] = "malformed message",
		[-MBX_E_UNKNOWN_CMD] = "unknown command",
		[-MBX_E_BAD_LINE] = "wrong line",
		[-MBX_E_NOT_REGISTERED] = "client not registered",
		[-MBX_E_ACCESS] = "access denied",
		[-MBX_E_PARAM] = "invalid parameter",
		[-MBX_E_TOO_BIG] = "data too large",
		[-MBX_E_BUSY] = "busy, retry",
		[-MBX_E_FULL] = "table full (the line's clients, or its watches)",
		[-MBX_E_QUEUE] = "client queue unusable",
		[-MBX_E_TIMEOUT] = "timed out",
		[-MBX_E_ABORT] = "aborted (see abort code)",
		[-MBX_E_STATE] = "not possible in the current state",
		[-MBX_E_UNSUPPORTED] = "not supported on this line",
		[-MBX_E_SEQUENCE] = "chunk out of sequence",
		[-MBX_E_OVERFLOW] = "messages dropped (queue full)",
		[-MBX_E_INTERNAL] = "internal error",
		[-MBX_E_SHUTDOWN] = "line shutting down",
		[-MBX_E_LSS] = "LSS slave reported an error",
		[-MBX_E_NOT_FOUND] =
			"not found: no such device object or node, or no LSS slave answered",
		[-MBX_E_NO_ANSWER] = "the device did not answer in time",
		[-MBX_E_NO_MEMORY] = "the daemon's transfer memory budget is spent (retry later)",
	};

	if (status > 0 || status <= -(int)(sizeof names / sizeof names[0]) || !names[-status])
		return "unknown status";
	return names[-status];
}

const char *mbx_bad_to_string(unsigned b)
{
	static const char *const names[MBX_BAD_COUNT] = {
		[MBX_BAD_NONE] = "none",         [MBX_BAD_SHORT] = "short",
		[MBX_BAD_MAGIC] = "magic",       [MBX_BAD_VERSION] = "version",
		[MBX_BAD_KIND] = "kind",         [MBX_BAD_LEN] = "length",
		[MBX_BAD_FLAGS] = "flags",       [MBX_BAD_CHUNK] = "chunk",
		[MBX_BAD_RESERVED] = "reserved", [MBX_BAD_LINE] = "line",
		[MBX_BAD_CMD] = "command",       [MBX_BAD_SIZE] = "size",
		[MBX_BAD_PARAM] = "parameter",   [MBX_BAD_CLIENT] = "client",
		[MBX_BAD_SEQUENCE] = "sequence", [MBX_BAD_QUEUE] = "queue",
	};
	return b < MBX_BAD_COUNT ? names[b] : "?";
}

int mbx_bad_status(mbx_bad b)
{
	switch (b) {
	case MBX_BAD_NONE:
		return MBX_OK;
	case MBX_BAD_VERSION:
		return MBX_E_VERSION;
	case MBX_BAD_LINE:
		return MBX_E_BAD_LINE;
	case MBX_BAD_CMD:
		return MBX_E_UNKNOWN_CMD;
	case MBX_BAD_PARAM:
		return MBX_E_PARAM;
	case MBX_BAD_CLIENT:
		return MBX_E_NOT_REGISTERED;
	case MBX_BAD_SEQUENCE:
		return MBX_E_SEQUENCE;
	case MBX_BAD_QUEUE:
		return MBX_E_QUEUE;
	default:
		return MBX_E_MALFORMED;
	}
}

const char *mbx_access_to_string(unsigned a)
{
	switch (a) {
	case MBX_ACCESS_NONE:
		return "none";
	case MBX_ACCESS_READ:
		return "read";
	case MBX_ACCESS_WRITE:
		return "write";
	}
	return "?";
}

const char *mbx_can_state_to_string(unsigned s)
{
	switch (s) {
	case MBX_CAN_ACTIVE:
		return "error-active";
	case MBX_CAN_WARNING:
		return "error-warning";
	case MBX_CAN_PASSIVE:
		return "error-passive";
	case MBX_CAN_BUS_OFF:
		return "bus-off";
	case MBX_CAN_STOPPED:
		return "stopped";
	}
	return "?";
}
