/* SPDX-License-Identifier: MIT */
/*
 * The two error tables, row by row: a daemon call's errno -> the mailbox
 * status its answer carries (mailbox/proto.h mbx_status_of_errno), and a
 * local failure in an SDO transfer -> the abort code on the wire
 * (core/sdo.h sdo_abort_of_errno). Every caller maps through these; a row
 * changed here changes every answer of that kind at once.
 */
#include <errno.h>
#include <stdio.h>

#include "unity.h"

#include "core/sdo.h"
#include "mailbox/proto.h"

void setUp(void) {}

void tearDown(void) {}

static const struct {
	int rc;
	int status;
} mbx_rows[] = {
	{ 0, MBX_OK },
	{ 3, MBX_OK }, /* a count or a channel: success */
	{ -EINVAL, MBX_E_PARAM },
	{ -ENOENT, MBX_E_PARAM },
	{ -ERANGE, MBX_E_PARAM },
	{ -ENOSPC, MBX_E_BUSY },
	{ -ENOBUFS, MBX_E_BUSY },
	{ -EBUSY, MBX_E_BUSY },
	{ -EAGAIN, MBX_E_STATE },
	{ -EPERM, MBX_E_STATE },
	{ -EEXIST, MBX_E_STATE },
	{ -ENODEV, MBX_E_UNSUPPORTED },
	{ -EOPNOTSUPP, MBX_E_UNSUPPORTED },
	{ -ENOMEM, MBX_E_NO_MEMORY },
	{ -EMSGSIZE, MBX_E_TOO_BIG },
	{ -E2BIG, MBX_E_TOO_BIG },
	{ -ETIMEDOUT, MBX_E_NO_ANSWER },
	{ -ESHUTDOWN, MBX_E_SHUTDOWN },
	{ -EIO, MBX_E_INTERNAL }, /* nobody expects it: the daemon failed */
	{ -EXDEV, MBX_E_INTERNAL },
};

static void test_errno_to_mailbox_status(void)
{
	for (size_t i = 0; i < sizeof mbx_rows / sizeof mbx_rows[0]; i++) {
		char msg[32];
		snprintf(msg, sizeof msg, "row %zu (errno %d)", i, -mbx_rows[i].rc);
		TEST_ASSERT_EQUAL_INT_MESSAGE(mbx_rows[i].status,
					      mbx_status_of_errno(mbx_rows[i].rc), msg);
	}
}

static const struct {
	int rc;
	uint32_t abort;
} sdo_rows[] = {
	{ 0, 0 },
	{ -ENOMEM, SDO_AB_NO_MEM },
	{ -EBUSY, SDO_AB_NO_RESOURCE },
	{ -ENOSPC, SDO_AB_NO_RESOURCE },
	{ -EALREADY, SDO_AB_ROUTE_BUSY },
	{ -EPERM, SDO_AB_DEV_STATE },
	{ -EAGAIN, SDO_AB_DEV_STATE },
	{ -EACCES, SDO_AB_LOCAL_CTRL },
	{ -ENODATA, SDO_AB_NO_DATA },
	{ -EINVAL, SDO_AB_VALUE },
	{ -EMSGSIZE, SDO_AB_LEN_HIGH },
	{ -EIO, SDO_AB_STORE }, /* a data source or sink failed */
	{ -ETIMEDOUT, SDO_AB_NODE_UNKNOWN },
	{ -ENODEV, SDO_AB_STORE }, /* nobody expects it: cannot transfer */
	{ -EXDEV, SDO_AB_STORE },
};

static void test_errno_to_sdo_abort(void)
{
	for (size_t i = 0; i < sizeof sdo_rows / sizeof sdo_rows[0]; i++) {
		char msg[32];
		snprintf(msg, sizeof msg, "row %zu (errno %d)", i, -sdo_rows[i].rc);
		TEST_ASSERT_EQUAL_HEX32_MESSAGE(sdo_rows[i].abort,
						sdo_abort_of_errno(sdo_rows[i].rc), msg);
	}
}

/* The codes are CiA 301 / 302-7's own numbers (not ours to choose). */
static void test_abort_codes_are_the_cia_numbers(void)
{
	TEST_ASSERT_EQUAL_HEX32(0x05040005, SDO_AB_NO_MEM);
	TEST_ASSERT_EQUAL_HEX32(0x060A0023, SDO_AB_NO_RESOURCE);
	TEST_ASSERT_EQUAL_HEX32(0x08000020, SDO_AB_STORE);
	TEST_ASSERT_EQUAL_HEX32(0x08000022, SDO_AB_DEV_STATE);
	TEST_ASSERT_EQUAL_HEX32(0x0A000002, SDO_AB_NODE_UNKNOWN);
	TEST_ASSERT_EQUAL_HEX32(0x0A000003, SDO_AB_ROUTE_BUSY);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_errno_to_mailbox_status);
	RUN_TEST(test_errno_to_sdo_abort);
	RUN_TEST(test_abort_codes_are_the_cia_numbers);
	return UNITY_END();
}
