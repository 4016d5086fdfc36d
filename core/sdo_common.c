/* SPDX-License-Identifier: MIT */
/*
 * What the SDO server and client share besides block transfer
 * (sdo_block.c): the abort code of a callee's errno, the names of the
 * transfer modes, and the layout of the channel parameter records (the
 * abort codes' names: sdo_abort.c).
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
