/* SPDX-License-Identifier: MIT */
/*
 * mailbox/budget.h: the transfer memory budget (limits, what read-only
 * transfers leave to writers, counters) and the transfer buffers whose
 * pages go back to the kernel after a big transfer (docs/config.md transfer_memory).
 */
#include <stdint.h>
#include <stdio.h>
#include <string.h>

#include "unity.h"

#include "mailbox/budget.h"

void setUp(void) {}

void tearDown(void) {}

static void test_budget_limits_and_counts(void)
{
	mbx_budget b;

	mbx_budget_init(&b, 1000);
	TEST_ASSERT_TRUE(mbx_budget_take(&b, 600, 0));
	TEST_ASSERT_FALSE(mbx_budget_take(&b, 401, 0)); /* would exceed */
	TEST_ASSERT_TRUE(mbx_budget_take(&b, 400, 0));  /* exactly the limit */
	TEST_ASSERT_EQUAL_UINT64(1000, mbx_budget_used(&b));
	mbx_budget_give(&b, 1000);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&b));
	TEST_ASSERT_FALSE(mbx_budget_take(&b, 1001, 0)); /* larger than all of it */
	TEST_ASSERT_EQUAL_UINT64(2, atomic_load(&b.refused));
	TEST_ASSERT_EQUAL_UINT64(1000, atomic_load(&b.peak));
	/* NULL: no budget configured, anything fits */
	TEST_ASSERT_TRUE(mbx_budget_take(NULL, UINT64_MAX / 2, 0));
	mbx_budget_give(NULL, 5);
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(NULL));
}

static void test_read_only_takes_leave_keep_free(void)
{
	mbx_budget b;

	mbx_budget_init(&b, 1000);
	/* a reader may use all but 300 (a writer's max_transfer) */
	TEST_ASSERT_TRUE(mbx_budget_take(&b, 700, 300));
	TEST_ASSERT_FALSE(mbx_budget_take(&b, 1, 300));
	/* a writer gets the rest */
	TEST_ASSERT_TRUE(mbx_budget_take(&b, 300, 0));
	mbx_budget_give(&b, 1000);
	TEST_ASSERT_FALSE(mbx_budget_take(&b, 800, 300));
	TEST_ASSERT_FALSE(mbx_budget_take(&b, 1, 1000)); /* keep_free = all */
}

static long rss_kb(void)
{
	FILE *f = fopen("/proc/self/status", "r");
	char line[256];
	long kb = -1;

	TEST_ASSERT_NOT_NULL(f);
	while (fgets(line, sizeof line, f))
		if (sscanf(line, "VmRSS: %ld", &kb) == 1)
			break;
	fclose(f);
	return kb;
}

static void test_buffer_pages_go_back_after_a_transfer(void)
{
	const size_t size = 16u << 20;
	uint8_t *buf = mbx_buffer_reserve(size);

	TEST_ASSERT_NOT_NULL(buf);
	long before = rss_kb();
	memset(buf, 0xA5, size); /* a 16 MiB transfer touches it all */
	long touched = rss_kb();
	mbx_buffer_release(buf, size);
	long after = rss_kb();
	printf("VmRSS %ld KiB, after touching 16 MiB %ld KiB, after release %ld KiB\n", before,
	       touched, after);
	TEST_ASSERT_TRUE(touched - before >= 15 * 1024);
	TEST_ASSERT_TRUE_MESSAGE(touched - after >= 15 * 1024, "the pages stayed resident");
	/* the first MBX_BUFFER_KEEP bytes keep their contents, the rest is
	 * fresh zero pages, and the whole buffer is usable again */
	TEST_ASSERT_EQUAL_HEX8(0xA5, buf[0]);
	TEST_ASSERT_EQUAL_HEX8(0xA5, buf[MBX_BUFFER_KEEP - 1]);
	TEST_ASSERT_EQUAL_HEX8(0, buf[MBX_BUFFER_KEEP]);
	TEST_ASSERT_EQUAL_HEX8(0, buf[size - 1]);
	buf[size - 1] = 7;
	TEST_ASSERT_EQUAL_HEX8(7, buf[size - 1]);
	/* nothing to give back for a small transfer */
	mbx_buffer_release(buf, MBX_BUFFER_KEEP);
	TEST_ASSERT_EQUAL_HEX8(0xA5, buf[MBX_BUFFER_KEEP - 1]);
	mbx_buffer_free(buf, size);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_budget_limits_and_counts);
	RUN_TEST(test_read_only_takes_leave_keep_free);
	RUN_TEST(test_buffer_pages_go_back_after_a_transfer);
	return UNITY_END();
}
