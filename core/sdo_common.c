/* SPDX-License-Identifier: MIT */
/*
 * What the SDO server and client share besides block transfer
 * (sdo_block.c): the strings for the CLI and logs, whose texts follow the
 * meaning of CiA 301 §7.2.4.3.17 in our own words, and the layout of the
 * channel parameter records.
 */
#include "core/sdo.h"

#include <errno.h>
#include <stddef.h>

static const struct {
	int err;
	uint32_t abort;
} abort_of_errno[] = {
	{ ENOMEM, SDO_AB_NO_MEM },       /* a buffer or the transfer budget */
	{ EBUSY, SDO_AB_NO_RESOURCE },   /* no SDO client channel free */
	{ ENOSPC, SDO_AB_NO_RESOURCE },  /* a bounded queue, a receiver */
	{ EALREADY, SDO_AB_ROUTE_BUSY }, /* the server is in another transfer */
	{ EPERM, SDO_AB_DEV_STATE },     /* the device state forbids it */
	{ EAGAIN, SDO_AB_DEV_STATE },
	{ EACCES, SDO_AB_LOCAL_CTRL },      /* local control forbids it */
	{ ENODATA, SDO_AB_NO_DATA },        /* no data available */
	{ EINVAL, SDO_AB_VALUE },           /* a value the callee refuses */
	{ EMSGSIZE, SDO_AB_LEN_HIGH },      /* larger than the object */
	{ ETIMEDOUT, SDO_AB_NODE_UNKNOWN }, /* nobody answered */
};

uint32_t sdo_abort_of_errno(int rc)
{
	if (rc >= 0)
		return 0;
	for (size_t i = 0; i < sizeof abort_of_errno / sizeof abort_of_errno[0]; i++)
		if (abort_of_errno[i].err == -rc)
			return abort_of_errno[i].abort;
	return SDO_AB_STORE;
}

const char *sdo_abort_to_string(uint32_t code)
{
	switch (code) {
	case SDO_OK:
		return "success";
	case SDO_AB_TOGGLE:
		return "toggle bit not alternated";
	case SDO_AB_TIMEOUT:
		return "SDO protocol timed out";
	case SDO_AB_CMD:
		return "command specifier not valid or unknown";
	case SDO_AB_BLK_SIZE:
		return "invalid block size";
	case SDO_AB_SEQ:
		return "invalid sequence number";
	case SDO_AB_CRC:
		return "CRC error";
	case SDO_AB_NO_MEM:
		return "out of memory";
	case SDO_AB_UNSUPP_ACCESS:
		return "unsupported access to an object";
	case SDO_AB_WRITE_ONLY:
		return "attempt to read a write only object";
	case SDO_AB_READ_ONLY:
		return "attempt to write a read only object";
	case SDO_AB_NO_OBJ:
		return "object does not exist";
	case SDO_AB_NO_MAP:
		return "object cannot be mapped to the PDO";
	case SDO_AB_MAP_LEN:
		return "mapped objects exceed the PDO length";
	case SDO_AB_PARAM_INCOMPAT:
		return "general parameter incompatibility";
	case SDO_AB_INTERNAL_INCOMPAT:
		return "general internal incompatibility";
	case SDO_AB_HW:
		return "access failed due to a hardware error";
	case SDO_AB_TYPE_LEN:
		return "data type does not match, length does not match";
	case SDO_AB_LEN_HIGH:
		return "data type does not match, length too high";
	case SDO_AB_LEN_LOW:
		return "data type does not match, length too low";
	case SDO_AB_NO_SUB:
		return "sub-index does not exist";
	case SDO_AB_VALUE:
		return "invalid value for parameter";
	case SDO_AB_VALUE_HIGH:
		return "value of parameter too high";
	case SDO_AB_VALUE_LOW:
		return "value of parameter too low";
	case SDO_AB_MAX_LT_MIN:
		return "maximum value is less than minimum value";
	case SDO_AB_NO_RESOURCE:
		return "resource not available: SDO connection";
	case SDO_AB_GENERAL:
		return "general error";
	case SDO_AB_STORE:
		return "data cannot be transferred or stored";
	case SDO_AB_LOCAL_CTRL:
		return "data cannot be transferred or stored: local control";
	case SDO_AB_DEV_STATE:
		return "data cannot be transferred or stored: device state";
	case SDO_AB_NO_OD:
		return "no object dictionary present";
	case SDO_AB_NO_DATA:
		return "no data available";
	case SDO_AB_NET_UNKNOWN:
		return "network unknown";
	case SDO_AB_NODE_UNKNOWN:
		return "node unknown or not answering";
	case SDO_AB_ROUTE_BUSY:
		return "routing channel busy";
	default:
		return "unknown abort code";
	}
}

int sdo_param_od_add(co_od *od, uint16_t idx, uint16_t sub0_access)
{
	int rc;

	if (co_od_has_index(od, idx))
		return 0;
	rc = co_od_ensure_num(od, idx, 0, CO_T_UNSIGNED8, sub0_access, 3, CO_OBJ_RECORD);
	for (uint8_t s = 1; !rc && s <= 2; s++)
		rc = co_od_ensure_num(od, idx, s, CO_T_UNSIGNED32, CO_ACC_RW, SDO_COB_INVALID,
				      CO_OBJ_RECORD);
	if (!rc)
		rc = co_od_ensure_num(od, idx, 3, CO_T_UNSIGNED8, CO_ACC_RW, 0, CO_OBJ_RECORD);
	return rc;
}

const char *sdo_mode_to_string(sdo_mode m)
{
	switch (m) {
	case SDO_MODE_AUTO:
		return "auto";
	case SDO_MODE_EXPEDITED:
		return "expedited";
	case SDO_MODE_SEGMENTED:
		return "segmented";
	case SDO_MODE_BLOCK:
		return "block";
	}
	return "?";
}
