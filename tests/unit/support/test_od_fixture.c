/* SPDX-License-Identifier: MIT */
#include <assert.h>
#include <string.h>

#include "tests/unit/support/test_od_fixture.h"

#define OK(x)                     \
	do {                      \
		int rc_ = (x);    \
		assert(rc_ == 0); \
		(void)rc_;        \
	} while (0)

static void rec_sub0(co_od *od, uint16_t idx, uint8_t n)
{
	co_od_entry *e;
	OK(co_od_add_num(od, idx, 0, CO_T_UNSIGNED8, CO_ACC_RO, n, &e));
	e->obj_code = CO_OBJ_RECORD;
}

co_od *fx_od_new(void)
{
	co_od *od;
	co_od_entry *e;
	const char *name = FX_DEVICE_NAME;

	OK(co_od_create(&od, 8));
	OK(co_od_add_num(od, 0x1000, 0, CO_T_UNSIGNED32, CO_ACC_RO, 0x00040194, NULL));
	OK(co_od_add_num(od, 0x1001, 0, CO_T_UNSIGNED8, CO_ACC_RO | CO_ACC_TPDO, 0, NULL));
	OK(co_od_add_bytes(od, 0x1008, 0, CO_T_VISIBLE_STRING, CO_ACC_CO, 64, name,
			   (uint32_t)strlen(name), NULL));
	OK(co_od_add_bytes(od, 0x1009, 0, CO_T_VISIBLE_STRING, CO_ACC_CO, 8, "0001", 4, NULL));
	OK(co_od_add_bytes(od, 0x100A, 0, CO_T_VISIBLE_STRING, CO_ACC_CO, 8, "0001", 4, NULL));
	OK(co_od_add_num(od, 0x1017, 0, CO_T_UNSIGNED16, CO_ACC_RW | CO_ACC_PERSIST, 1000, NULL));
	rec_sub0(od, 0x1018, 4);
	OK(co_od_add_num(od, 0x1018, 1, CO_T_UNSIGNED32, CO_ACC_RO, 0x250, NULL));
	OK(co_od_add_num(od, 0x1018, 2, CO_T_UNSIGNED32, CO_ACC_RO, 0, NULL));
	OK(co_od_add_num(od, 0x1018, 3, CO_T_UNSIGNED32, CO_ACC_RO, 0, NULL));
	OK(co_od_add_num(od, 0x1018, 4, CO_T_UNSIGNED32, CO_ACC_RO, FX_SERIAL, NULL));
	rec_sub0(od, 0x1800, 5);
	OK(co_od_add_num(od, 0x1800, 1, CO_T_UNSIGNED32, CO_ACC_RW, 0x181, NULL));
	OK(co_od_add_num(od, 0x1800, 2, CO_T_UNSIGNED8, CO_ACC_RW, 0xFE, NULL));
	OK(co_od_add_num(od, 0x1800, 3, CO_T_UNSIGNED16, CO_ACC_RW, 100, NULL));
	OK(co_od_add_num(od, 0x1800, 5, CO_T_UNSIGNED16, CO_ACC_RW, 1000, NULL));
	OK(co_od_add_num(od, 0x2003, 0, CO_T_REAL32, CO_ACC_RO | CO_ACC_TPDO, 0, NULL));
	rec_sub0(od, 0x2004, 1);
	OK(co_od_add_num(od, 0x2004, 1, CO_T_REAL32, CO_ACC_RW | CO_ACC_PERSIST, 0, NULL));
	rec_sub0(od, 0x2005, 1);
	OK(co_od_add_num(od, 0x2005, 1, CO_T_REAL32, CO_ACC_RW, 0x42C80000u /* 100.0f */, NULL));

	OK(co_od_add_num(od, FX_IDX_WO, 0, CO_T_UNSIGNED8, CO_ACC_WO, 0, NULL));
	OK(co_od_add_num(od, FX_IDX_LIMITED, 0, CO_T_UNSIGNED16, CO_ACC_RW, 100, &e));
	OK(co_od_entry_set_limits(e, 10, 1000));
	OK(co_od_add_num(od, FX_IDX_BOOL, 0, CO_T_BOOLEAN, CO_ACC_RW, 0, NULL));
	OK(co_od_add_num(od, FX_IDX_SIGNED, 0, CO_T_INTEGER16, CO_ACC_RW, 0, &e));
	OK(co_od_entry_set_limits(e, (uint64_t)(int64_t)-100, 100));
	rec_sub0(od, FX_IDX_GAPS, 3);
	OK(co_od_add_num(od, FX_IDX_GAPS, 1, CO_T_UNSIGNED8, CO_ACC_RW, 1, NULL));
	OK(co_od_add_num(od, FX_IDX_GAPS, 3, CO_T_UNSIGNED8, CO_ACC_RW, 3, NULL));
	OK(co_od_add_bytes(od, FX_IDX_DOMAIN, 0, CO_T_DOMAIN, CO_ACC_RW, FX_DOMAIN_MAX, NULL, 0,
			   NULL));
	OK(co_od_add_bytes(od, FX_IDX_OCTETS, 0, CO_T_OCTET_STRING, CO_ACC_RW, 1000, NULL, 0,
			   NULL));
	OK(co_od_add_num(od, FX_IDX_CONST, 0, CO_T_UNSIGNED32, CO_ACC_CO, 0xC0FFEE, NULL));
	OK(co_od_add_num(od, FX_IDX_HOOKED, 0, CO_T_UNSIGNED32, CO_ACC_RW, 7, NULL));
	OK(co_od_add_num(od, FX_IDX_U64, 0, CO_T_UNSIGNED64, CO_ACC_RW, 0, NULL));
	OK(co_od_add_bytes(od, FX_IDX_STR, 0, CO_T_VISIBLE_STRING, CO_ACC_RW, 64, "hi", 2, NULL));
	return od;
}
