/* SPDX-License-Identifier: MIT */
/*
 * The transfer memory budget (mailbox/budget.h) under ThreadSanitizer: one
 * thread per "line" taking and giving back transfer sizes as fast as it
 * can, as line threads do with one budget for all lines. Checked: no data
 * race; what the threads hold together never exceeds the limit (each
 * thread adds what it holds to a shared tally after a take and removes it
 * before the give); a read-only take always leaves keep_free; every refusal
 * is counted; at the end nothing is taken and the peak is within the limit.
 */
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>

#include "unity.h"

#include "mailbox/budget.h"

#define THREADS 4
#define ROUNDS 200000u
#define LIMIT (1u << 20)
#define KEEP (256u * 1024u)

static mbx_budget budget;
static _Atomic uint64_t held, over_limit, refusals;

static void *line_thread(void *arg)
{
	uint64_t seed = (uint64_t)(uintptr_t)arg * 0x9E3779B97F4A7C15ull + 1;

	for (unsigned i = 0; i < ROUNDS; i++) {
		seed ^= seed << 13;
		seed ^= seed >> 7;
		seed ^= seed << 17;
		uint64_t n = 1 + seed % (LIMIT / 2);
		bool reader = seed & 0x100000u;
		if (!mbx_budget_take(&budget, n, reader ? KEEP : 0)) {
			atomic_fetch_add(&refusals, 1);
			continue;
		}
		uint64_t now = atomic_fetch_add(&held, n) + n;
		if (now > LIMIT)
			atomic_fetch_add(&over_limit, 1);
		atomic_fetch_sub(&held, n);
		mbx_budget_give(&budget, n);
	}
	return NULL;
}

void setUp(void) {}

void tearDown(void) {}

static void test_lines_share_one_budget_without_a_lock(void)
{
	pthread_t t[THREADS];

	mbx_budget_init(&budget, LIMIT);
	for (uintptr_t i = 0; i < THREADS; i++)
		TEST_ASSERT_EQUAL_INT(0, pthread_create(&t[i], NULL, line_thread, (void *)(i + 1)));
	for (unsigned i = 0; i < THREADS; i++)
		pthread_join(t[i], NULL);
	TEST_ASSERT_EQUAL_UINT64(0, atomic_load(&over_limit));
	TEST_ASSERT_EQUAL_UINT64(0, mbx_budget_used(&budget));
	TEST_ASSERT_TRUE(atomic_load(&budget.peak) <= LIMIT);
	TEST_ASSERT_EQUAL_UINT64(atomic_load(&refusals), atomic_load(&budget.refused));
	TEST_ASSERT_TRUE_MESSAGE(atomic_load(&refusals) > 0, "the budget never ran out");
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_lines_share_one_budget_without_a_lock);
	return UNITY_END();
}
