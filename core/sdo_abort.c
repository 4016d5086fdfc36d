/* SPDX-License-Identifier: MIT */
/*
 * The names of the SDO abort codes (CiA 301 §7.2.4.3.17, table 22), in our
 * own words, for the CLI, the logs and every client: alone in its file so
 * that libcogw.so carries the same table (mailbox/cogw.h "Errors"; the
 * Python package names its exceptions' aborts with it, docs/python.md).
 */
#include "core/sdo.h"

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
