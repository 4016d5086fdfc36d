/* Decoding SocketCAN error frames into CAN bus states (lines/socketcan.c).
 * vcan never produces error frames, so the decoder is checked here with the
 * frames a real controller driver sends (linux/can/error.h layouts). */
#include <linux/can.h>
#include <linux/can/error.h>

#include "lines/socketcan.h"
#include "unity.h"

void setUp(void) {}
void tearDown(void) {}

static can_error_info decode(uint32_t cls, uint8_t d1, can_bus_state from)
{
	uint8_t data[8] = { 0, d1, 0, 0, 0, 0, 0, 0 };
	can_error_info info;
	can_error_decode(CAN_ERR_FLAG | cls, data, from, &info);
	return info;
}

static void test_warning_then_passive_then_bus_off_then_restart(void)
{
	can_error_info i = decode(CAN_ERR_CRTL, CAN_ERR_CRTL_TX_WARNING, CAN_BUS_ACTIVE);
	TEST_ASSERT_TRUE(i.state_changed);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_WARNING, i.state);

	i = decode(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_PASSIVE, CAN_BUS_WARNING);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_PASSIVE, i.state);

	i = decode(CAN_ERR_BUSOFF, 0, CAN_BUS_PASSIVE);
	TEST_ASSERT_TRUE(i.state_changed);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_OFF, i.state);

	i = decode(CAN_ERR_RESTARTED, 0, CAN_BUS_OFF);
	TEST_ASSERT_TRUE(i.restarted);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_ACTIVE, i.state);
	TEST_ASSERT_EQUAL_STRING("error-active", can_bus_state_to_string(i.state));
}

static void test_back_to_active_is_a_change(void)
{
	can_error_info i = decode(CAN_ERR_CRTL, CAN_ERR_CRTL_ACTIVE, CAN_BUS_PASSIVE);
	TEST_ASSERT_TRUE(i.state_changed);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_ACTIVE, i.state);
}

static void test_protocol_and_controller_problems_keep_the_state(void)
{
	can_error_info i = decode(CAN_ERR_PROT | CAN_ERR_BUSERROR, 0, CAN_BUS_WARNING);
	TEST_ASSERT_FALSE(i.state_changed);
	TEST_ASSERT_EQUAL_INT(CAN_BUS_WARNING, i.state);
	TEST_ASSERT_TRUE(i.protocol_violation);
	TEST_ASSERT_TRUE(i.bus_error);

	i = decode(CAN_ERR_CRTL, CAN_ERR_CRTL_RX_OVERFLOW, CAN_BUS_ACTIVE);
	TEST_ASSERT_TRUE(i.controller_problem);
	TEST_ASSERT_FALSE(i.state_changed);

	i = decode(CAN_ERR_ACK | CAN_ERR_TX_TIMEOUT | CAN_ERR_LOSTARB, 0, CAN_BUS_ACTIVE);
	TEST_ASSERT_TRUE(i.no_ack);
	TEST_ASSERT_TRUE(i.tx_timeout);
	TEST_ASSERT_TRUE(i.lost_arbitration);
}

static void test_error_counters_are_read_when_present(void)
{
	uint8_t data[8] = { 0, 0, 0, 0, 0, 0, 131, 7 };
	can_error_info i;
	can_error_decode(CAN_ERR_FLAG | CAN_ERR_CNT, data, CAN_BUS_ACTIVE, &i);
	TEST_ASSERT_EQUAL_UINT8(131, i.tx_errors);
	TEST_ASSERT_EQUAL_UINT8(7, i.rx_errors);
	can_error_decode(CAN_ERR_FLAG | CAN_ERR_PROT, data, CAN_BUS_ACTIVE, &i);
	TEST_ASSERT_EQUAL_UINT8(0, i.tx_errors);
}

int main(void)
{
	UNITY_BEGIN();
	RUN_TEST(test_warning_then_passive_then_bus_off_then_restart);
	RUN_TEST(test_back_to_active_is_a_change);
	RUN_TEST(test_protocol_and_controller_problems_keep_the_state);
	RUN_TEST(test_error_counters_are_read_when_present);
	return UNITY_END();
}
