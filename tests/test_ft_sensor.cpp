// The Net CAN OEM protocol, and the F/T driver against the simulated sensor.
//
// Every driver test runs on two buses: a socketpair carrying can_frame records (always), and a
// real SocketCAN interface when STEPCAL_CAN_IFACE names one (ctest label vcan runs this binary
// inside tests/system/vcan_run.sh with STEPCAL_CAN_IFACE=vcan0). On CAN the kernel filters the sensor's
// ids; on the socketpair every frame reaches the driver.
#include <gtest/gtest.h>
#include <sys/socket.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <thread>

#include "stepcal/common/error.hpp"
#include "stepcal/ftsim/simulator.hpp"
#include "stepcal/runtime/ft_sensor.hpp"
#include "stepcal/allocation_counter.hpp"
#include "support/input_error.hpp"

namespace {

using namespace stepcal;
using namespace stepcal::runtime;
using netcan::Opcode;
using std::chrono::milliseconds;

// ---------------------------------------------------------------- protocol (no bus)

TEST(NetCan, FrameIdsAreBaseShiftedByFourOrOpcode) {
  EXPECT_EQ(netcan::frameId(0x20, Opcode::kReadGauges), 0x200u);
  EXPECT_EQ(netcan::frameId(0x20, Opcode::kGaugesSecond), 0x201u);
  EXPECT_EQ(netcan::frameId(0x7F, Opcode::kReadFirmware), 0x7FFu);
  EXPECT_EQ(netcan::frameId(0x00, Opcode::kReset), 0x00Cu);
}

TEST(NetCan, GaugeRepliesAreBigEndianWithStatusFirst) {
  const auto frames = netcan::encodeGauges(0x20, 0x8001, {0x0102, -2, 0x0304, 0x7FFF, -32768, 5});
  EXPECT_EQ(frames[0].can_id, 0x200u);
  ASSERT_EQ(frames[0].can_dlc, 8);
  const uint8_t first[8] = {0x80, 0x01, 0x01, 0x02, 0x03, 0x04, 0x80, 0x00};  // status, g0, g2, g4
  for (int k = 0; k < 8; ++k) EXPECT_EQ(frames[0].data[k], first[k]) << k;
  EXPECT_EQ(frames[1].can_id, 0x201u);
  ASSERT_EQ(frames[1].can_dlc, 6);
  const uint8_t second[6] = {0xFF, 0xFE, 0x7F, 0xFF, 0x00, 0x05};  // g1, g3, g5
  for (int k = 0; k < 6; ++k) EXPECT_EQ(frames[1].data[k], second[k]) << k;

  netcan::GaugeAssembler assembler;
  netcan::GaugeReading reading;
  EXPECT_FALSE(assembler.second(frames[1], reading)) << "a second half alone is no reading";
  EXPECT_TRUE(assembler.first(frames[0]));
  ASSERT_TRUE(assembler.second(frames[1], reading));
  EXPECT_EQ(reading.status_word, 0x8001);
  const std::array<int16_t, 6> expected{0x0102, -2, 0x0304, 0x7FFF, -32768, 5};
  EXPECT_EQ(reading.gauges, expected);
}

TEST(NetCan, MatrixRowsAreBigEndianFloats) {
  netcan::Calibration calibration;
  for (int k = 0; k < 36; ++k) calibration.matrix[size_t(k)] = float(k) + 0.5f;
  calibration.matrix[6 * 2 + 1] = 1.0f;  // 0x3F800000
  const auto frames = netcan::encodeMatrixRow(0x20, calibration, 2);
  EXPECT_EQ(frames[0].can_id, 0x202u);
  EXPECT_EQ(frames[1].can_id, 0x203u);
  EXPECT_EQ(frames[2].can_id, 0x204u);
  EXPECT_EQ(frames[0].data[4], 0x3F);
  EXPECT_EQ(frames[0].data[5], 0x80);
  EXPECT_EQ(frames[0].data[6], 0x00);
  for (int k = 0; k < 3; ++k) {
    EXPECT_EQ(netcan::readF32(frames[size_t(k)].data), calibration.matrix[size_t(12 + 2 * k)]);
  }
}

TEST(NetCan, ClassifiesEveryKindOfFrame) {
  const uint32_t base = 0x20;
  const auto gauges = netcan::encodeGauges(base, 0, {});
  EXPECT_EQ(netcan::classify(gauges[0], base), netcan::FrameKind::kGaugesFirst);
  EXPECT_EQ(netcan::classify(gauges[1], base), netcan::FrameKind::kGaugesSecond);
  uint8_t data[8] = {};
  EXPECT_EQ(netcan::classify(netcan::makeFrame(base, Opcode::kReadSerial, data, 8), base),
            netcan::FrameKind::kReply);
  EXPECT_EQ(netcan::classify(netcan::makeFrame(base, Opcode::kReadSerial, data, 7), base),
            netcan::FrameKind::kBadLength);
  EXPECT_EQ(netcan::classify(netcan::makeFrame(base, Opcode::kReadGauges), base),
            netcan::FrameKind::kBadLength)
      << "a gauge request (another master) is not a reply";
  EXPECT_EQ(netcan::classify(netcan::makeFrame(base, Opcode::kReset), base),
            netcan::FrameKind::kUnknownOpcode);
  EXPECT_EQ(netcan::classify(netcan::makeFrame(0x21, Opcode::kReadGauges, data, 8), base),
            netcan::FrameKind::kForeignId);
  can_frame extended = gauges[0];
  extended.can_id |= CAN_EFF_FLAG;
  EXPECT_EQ(netcan::classify(extended, base), netcan::FrameKind::kForeignId);
  EXPECT_EQ(netcan::classify(ftsim::errorFrame(CAN_ERR_BUSOFF), base), netcan::FrameKind::kError);
}

TEST(NetCan, StatusWordNamesItsBits) {
  EXPECT_EQ(netcan::describeStatus(0), "");
  EXPECT_EQ(netcan::describeStatus(netcan::status_bit::kPowerSupplyTooLow | netcan::status_bit::kAnyError),
            "power supply too low, error");
  EXPECT_EQ(netcan::describeStatus(1u << 9), "reserved bits 0x200");
  EXPECT_TRUE(netcan::status_bit::kCritical & netcan::status_bit::kEepromFailure);
  EXPECT_FALSE(netcan::status_bit::kCritical & netcan::status_bit::kWatchdogReset);
}

/// A calibration whose products and sums are exact in double: dyadic entries, power-of-two counts.
netcan::Calibration dyadicCalibration() {
  netcan::Calibration calibration;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) {
      calibration.matrix[size_t(6 * i + j)] = (i == j ? 40.0f : 0.0f) + float((i * 7 + j * 3) % 9 - 4) * 0.125f;
    }
  }
  calibration.counts_per_force = 1024;
  calibration.counts_per_torque = 8192;
  return calibration;
}

/// The manual's formula evaluated exactly (long double holds every intermediate here exactly).
Vec6 exactWrench(const netcan::Calibration& calibration, const std::array<int16_t, 6>& gauges) {
  Vec6 wrench;
  for (int i = 0; i < 6; ++i) {
    long double counts = 0;
    for (int j = 0; j < 6; ++j) counts += (long double)calibration.matrix[size_t(6 * i + j)] * gauges[size_t(j)];
    wrench[i] = double(counts / (i < 3 ? calibration.counts_per_force : calibration.counts_per_torque));
  }
  return wrench;
}

TEST(NetCan, ConverterIsBitExactOnADyadicCalibration) {
  const netcan::Calibration calibration = dyadicCalibration();
  const netcan::WrenchConverter converter(calibration);
  const std::array<std::array<int16_t, 6>, 4> cases{{{0, 0, 0, 0, 0, 0},
                                                     {1, -1, 2, -2, 3, -3},
                                                     {32767, -32768, 12345, -23456, 7, 0},
                                                     {-32768, -32768, -32768, 32767, 32767, 32767}}};
  for (const auto& gauges : cases) {
    const Vec6 wrench = converter.wrench(gauges, Vec6::Zero());
    const Vec6 expected = exactWrench(calibration, gauges);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(wrench[i], expected[i]) << "axis " << i;
  }
}

TEST(NetCan, ConverterConvertsUnitsAndInvertsItself) {
  netcan::Calibration calibration = ftsim::defaultCalibration();
  calibration.force_unit = 1;   // lbf
  calibration.torque_unit = 2;  // lbf·ft
  const netcan::WrenchConverter converter(calibration);
  const Vec6 wrench = (Vec6() << 120.0, -40.0, 530.0, 12.0, -7.5, 3.25).finished();
  const Vec6 gauges = converter.gaugesFor(wrench);
  std::array<int16_t, 6> rounded{};
  for (int j = 0; j < 6; ++j) rounded[size_t(j)] = int16_t(std::lround(gauges[j]));
  // Unrounded gauges reproduce the wrench to rounding; rounded ones to half a count each.
  Vec6 from_real = Vec6::Zero();
  const netcan::Calibration& c = calibration;
  for (int i = 0; i < 6; ++i) {
    for (int j = 0; j < 6; ++j) from_real[i] += double(c.matrix[size_t(6 * i + j)]) * gauges[j];
    from_real[i] *= i < 3 ? 4.4482216152605 / c.counts_per_force
                          : 12 * 0.0254 * 4.4482216152605 / c.counts_per_torque;
  }
  EXPECT_LT((from_real - wrench).norm(), 1e-9);
  const Vec6 decoded = converter.wrench(rounded, Vec6::Zero());
  EXPECT_LT((decoded.head<3>() - wrench.head<3>()).cwiseAbs().maxCoeff(), 0.5);
  EXPECT_LT((decoded.tail<3>() - wrench.tail<3>()).cwiseAbs().maxCoeff(), 0.05);
}

TEST(NetCan, ConverterRefusesBadCalibrations) {
  netcan::Calibration nan_entry = ftsim::defaultCalibration();
  nan_entry.matrix[7] = std::nanf("");
  test::expectInputError([&] { netcan::WrenchConverter{nan_entry}; }, {"row 1 column 1", "finite"});
  netcan::Calibration singular = ftsim::defaultCalibration();
  for (int j = 0; j < 6; ++j) singular.matrix[size_t(6 * 5 + j)] = singular.matrix[size_t(6 * 4 + j)];
  test::expectInputError([&] { netcan::WrenchConverter{singular}; }, {"rank 5", "expected 6"});
  netcan::Calibration no_counts = ftsim::defaultCalibration();
  no_counts.counts_per_torque = 0;
  test::expectInputError([&] { netcan::WrenchConverter{no_counts}; }, {"counts per unit", "> 0"});
  netcan::Calibration bad_unit = ftsim::defaultCalibration();
  bad_unit.force_unit = 9;
  test::expectInputError([&] { netcan::WrenchConverter{bad_unit}; }, {"unit codes are 9", "lbf, N"});
}

// ---------------------------------------------------------------- driver against the simulator

/// Two ends of a bus: the driver's and the sensor's, plus a way to inject frames as the bus
/// (error frames, garbage) would deliver them to the driver.
struct Bus {
  CanSocket driver_end;
  CanSocket sensor_end;
  CanSocket injector;
  bool kernel_filters = false;  ///< foreign ids never reach the driver
};

const char* canInterface() { return std::getenv("STEPCAL_CAN_IFACE"); }

Bus makeBus(const std::string& transport, uint32_t base_id) {
  if (transport == "socketpair") {
    int pair[2];
    EXPECT_EQ(socketpair(AF_UNIX, SOCK_SEQPACKET | SOCK_CLOEXEC, 0, pair), 0);
    const int injector = dup(pair[1]);
    return Bus{CanSocket::adopt(pair[0], "socketpair"), CanSocket::adopt(pair[1], "socketpair"),
               CanSocket::adopt(injector, "socketpair"), false};
  }
  const std::string iface = canInterface();
  can_filter sensor_side = sensorFilter(base_id);
  return Bus{CanSocket::open(iface, {sensorFilter(base_id)}, kSensorErrorMask),
             CanSocket::open(iface, {sensor_side}, 0), CanSocket::open(iface, {}, 0), true};
}

/// Collects published samples (driver thread) for the test thread.
class RecordingSink final : public WrenchSink {
 public:
  void publish(const WrenchSample& sample) noexcept override {
    slot.publish(sample);
    count.fetch_add(1);
  }
  WrenchSlot slot;
  std::atomic<int64_t> count{0};
};

class DriverTest : public testing::TestWithParam<std::string> {
 protected:
  void SetUp() override {
    if (GetParam() == "vcan" && canInterface() == nullptr) {
      GTEST_SKIP() << "STEPCAL_CAN_IFACE not set (ctest label vcan runs these in the VM)";
    }
  }
  void TearDown() override { stopAll(); }

  /// Starts the simulator serving on its end of a new bus.
  void startSensor(ftsim::SimulatorOptions options = {}) {
    bus_ = std::make_unique<Bus>(makeBus(GetParam(), options.base_id));
    simulator_ = std::make_unique<ftsim::SensorSimulator>(options);
    sensor_thread_ = std::thread([this] { simulator_->serve(bus_->sensor_end, stop_sensor_); });
  }
  /// The driver on the driver's end of the bus; the fixture owns it (its thread stops first).
  FtSensorDriver* makeDriver(FtSensorOptions options = {}) {
    options.base_id = simulator_->options().base_id;
    driver_owned_ = std::make_unique<FtSensorDriver>(std::move(bus_->driver_end), options);
    return driver_owned_.get();
  }
  void runDriver(FtSensorDriver& driver) {
    driver_ = &driver;
    driver_thread_ = std::thread([this] { driver_->run(sink_); });
  }
  /// Waits until done() holds; false after timeout (a loaded machine only makes it wait longer).
  template <typename Done>
  bool waitFor(Done done, milliseconds timeout = milliseconds(5000)) {
    const auto until = std::chrono::steady_clock::now() + timeout;
    while (!done()) {
      if (std::chrono::steady_clock::now() > until) return false;
      std::this_thread::sleep_for(milliseconds(1));
    }
    return true;
  }
  /// Waits until the sink has seen `more` further samples; false after timeout.
  bool waitSamples(int64_t more, milliseconds timeout = milliseconds(5000)) {
    const int64_t target = sink_.count.load() + more;
    return waitFor([&] { return sink_.count.load() >= target; }, timeout);
  }
  WrenchSample latest() const {
    WrenchSample sample;
    EXPECT_TRUE(sink_.slot.read(sample));
    return sample;
  }
  void inject(const can_frame& frame) { ASSERT_EQ(bus_->injector.send(frame), CanIo::kOk); }
  void stopAll() {
    if (driver_thread_.joinable()) {
      driver_->stop();
      driver_thread_.join();
    }
    driver_owned_.reset();
    stop_sensor_.store(true);
    if (sensor_thread_.joinable()) sensor_thread_.join();
  }
  Clock::time_point in(milliseconds d) const { return Clock::now() + d; }

  std::unique_ptr<Bus> bus_;
  std::unique_ptr<ftsim::SensorSimulator> simulator_;
  std::atomic<bool> stop_sensor_{false};
  std::thread sensor_thread_, driver_thread_;
  FtSensorDriver* driver_ = nullptr;
  std::unique_ptr<FtSensorDriver> driver_owned_;
  RecordingSink sink_;
};

const Vec6 kPayloadWrench = (Vec6() << 12.5, -31.0, -402.0, 18.25, 9.5, -1.75).finished();

TEST_P(DriverTest, ReadsIdentityAndCalibrationAtStartUp) {
  ftsim::SimulatorOptions options;
  options.serial = "FT31337";
  options.firmware_build = 1234;
  startSensor(options);
  FtSensorDriver* const driver = makeDriver();
  const FtSensorIdentity& identity = driver->identity();
  EXPECT_EQ(identity.serial, "FT31337");
  EXPECT_EQ(identity.firmware_major, options.firmware_major);
  EXPECT_EQ(identity.firmware_minor, options.firmware_minor);
  EXPECT_EQ(identity.firmware_build, 1234);
  EXPECT_EQ(identity.calibration_index, 0);
  EXPECT_EQ(identity.calibration.matrix, options.calibration.matrix) << "floats bit for bit";
  EXPECT_EQ(identity.calibration.counts_per_force, options.calibration.counts_per_force);
  EXPECT_EQ(identity.calibration.counts_per_torque, options.calibration.counts_per_torque);
  EXPECT_EQ(identity.calibration.force_unit, 2);
  EXPECT_EQ(identity.calibration.torque_unit, 3);
}

TEST_P(DriverTest, StartUpWithoutASensorNamesWhatFailed) {
  startSensor();
  ftsim::Faults faults;
  faults.stalled = true;
  simulator_->setFaults(faults);
  FtSensorOptions options;
  options.startup_timeout_ns = 20'000'000;
  options.startup_attempts = 2;
  test::expectInputError([&] { makeDriver(options); },
                         {"base id 0x20", "set active calibration 0", "id 0x206", "20 ms",
                          "2 attempts", "powered"});
}

TEST_P(DriverTest, RefusedCalibrationIndexIsAnError) {
  startSensor();
  FtSensorOptions options;
  options.calibration_index = 3;
  test::expectInputError([&] { makeDriver(options); }, {"refused calibration index 3"});
}

TEST_P(DriverTest, GaugesBecomeTheExactWrench) {
  ftsim::SimulatorOptions options;
  options.calibration = dyadicCalibration();
  startSensor(options);
  FtSensorDriver* const driver = makeDriver();
  const std::array<std::array<int16_t, 6>, 3> cases{
      {{100, -200, 300, -400, 500, -600}, {32767, -32768, 0, 1, -1, 12345}, {0, 0, 0, 0, 0, 0}}};
  for (const auto& gauges : cases) {
    simulator_->setGauges(gauges);
    WrenchSample sample;
    ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
    const Vec6 expected = exactWrench(options.calibration, gauges);
    for (int i = 0; i < 6; ++i) EXPECT_EQ(sample.wrench_Sensor[i], expected[i]) << "axis " << i;
    EXPECT_EQ(sample.sensor_status, 0u);
  }
  EXPECT_EQ(driver->counters().samples, 3);
}

TEST_P(DriverTest, StampIsTheKernelReceiveTime) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  for (int k = 0; k < 20; ++k) {
    const int64_t before_ns = steadyNowNs();
    WrenchSample sample;
    ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
    const int64_t after_ns = steadyNowNs();
    EXPECT_GE(sample.stamp_ns, before_ns);
    EXPECT_LE(sample.stamp_ns, after_ns);
    EXPECT_EQ(sample.sequence, uint64_t(k + 1));
  }
}

TEST_P(DriverTest, WrenchRoundTripsWithinOneGaugeCount) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  WrenchSample sample;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  // Rounding to whole gauge counts: ≤ ½ count per gauge through the matrix (≈ 0.05 N, 0.005 N·m).
  EXPECT_LT((sample.wrench_Sensor.head<3>() - kPayloadWrench.head<3>()).cwiseAbs().maxCoeff(), 0.06);
  EXPECT_LT((sample.wrench_Sensor.tail<3>() - kPayloadWrench.tail<3>()).cwiseAbs().maxCoeff(), 0.006);
}

TEST_P(DriverTest, BiasRemovesTheUnloadedReading) {
  ftsim::SimulatorOptions options;
  options.offset_Sensor << 35.0, -12.0, 80.0, 2.5, -1.5, 0.75;
  startSensor(options);
  FtSensorOptions driver_options;
  driver_options.bias_samples = 4;
  FtSensorDriver* const driver = makeDriver(driver_options);
  WrenchSample sample;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  EXPECT_LT((sample.wrench_Sensor - options.offset_Sensor).head<3>().norm(), 0.1) << "no bias yet";

  driver->requestBias();
  runDriver(*driver);
  ASSERT_TRUE(waitSamples(10));
  EXPECT_TRUE(driver->biased());
  EXPECT_LT(latest().wrench_Sensor.norm(), 1e-9) << "same gauges as at the tare";
  simulator_->setWrench(kPayloadWrench);
  ASSERT_TRUE(waitSamples(5));
  const Vec6 tared = latest().wrench_Sensor;
  EXPECT_LT((tared.head<3>() - kPayloadWrench.head<3>()).cwiseAbs().maxCoeff(), 0.1);
  EXPECT_LT((tared.tail<3>() - kPayloadWrench.tail<3>()).cwiseAbs().maxCoeff(), 0.01);

  driver->clearBias();
  ASSERT_TRUE(waitSamples(5));
  EXPECT_FALSE(driver->biased());
  EXPECT_LT((latest().wrench_Sensor - kPayloadWrench - options.offset_Sensor).head<3>().norm(), 0.1);
}

TEST_P(DriverTest, AStalledSensorTimesOutAndTheWrenchGoesStale) {
  startSensor();
  FtSensorOptions options;
  options.poll_hz = 500.0;
  FtSensorDriver* const driver = makeDriver(options);
  simulator_->setWrench(kPayloadWrench);
  runDriver(*driver);
  ASSERT_TRUE(waitSamples(5));
  constexpr int64_t kMaxAgeNs = 20'000'000;
  Vec6 wrench;
  // Fresh: asked 1 ms after the latest sample (not "now": a descheduled test would age it).
  EXPECT_EQ(wrenchFor(sink_.slot, latest().stamp_ns + 1'000'000, kMaxAgeNs, wrench), Status::kOk);

  ftsim::Faults stall;
  stall.stalled = true;
  simulator_->setFaults(stall);
  // Counted, not timed: 25 timeouts end ≥ 23 poll periods (46 ms at 500 Hz) after the last
  // sample (at most the first could still be answered late), past the 20 ms age limit.
  const int64_t timeouts_before = driver->counters().timeouts;
  ASSERT_TRUE(waitFor([&] { return driver->counters().timeouts >= timeouts_before + 25; }));
  EXPECT_EQ(wrenchFor(sink_.slot, steadyNowNs(), kMaxAgeNs, wrench), Status::kStaleWrench);

  simulator_->setFaults({});
  ASSERT_TRUE(waitSamples(5));
  EXPECT_EQ(wrenchFor(sink_.slot, latest().stamp_ns + 1'000'000, kMaxAgeNs, wrench), Status::kOk);
}

TEST_P(DriverTest, ASensorBackFromASilenceIsReadAgainBeforeItsGaugesCount) {
  startSensor();
  FtSensorOptions options;
  options.poll_hz = 500.0;
  options.bias_samples = 1;
  options.resync_after_silence_ns = 50'000'000;
  options.bus_off_probe_ns = 20'000'000;
  FtSensorDriver* const driver = makeDriver(options);
  simulator_->setWrench(kPayloadWrench);
  driver->requestBias();
  runDriver(*driver);
  ASSERT_TRUE(waitFor([&] { return driver->biased(); }));

  // The same sensor silent for a while: read again, nothing changed, the tare stays.
  ftsim::Faults stall;
  stall.stalled = true;
  simulator_->setFaults(stall);
  // The driver measures the silence on the clock: 200 ms is past 50 ms however it is scheduled.
  std::this_thread::sleep_for(milliseconds(200));
  simulator_->setFaults({});
  ASSERT_TRUE(waitFor([&] { return driver->counters().resyncs == 1; }));
  EXPECT_TRUE(driver->biased());

  // Restarted with another calibration: after the silence the new matrix decodes its gauges
  // (the old one would read the wrench 1/1.25 too small) and the tare is gone.
  stop_sensor_.store(true);
  sensor_thread_.join();
  ftsim::SimulatorOptions recalibrated;
  for (float& entry : recalibrated.calibration.matrix) entry *= 1.25f;
  simulator_ = std::make_unique<ftsim::SensorSimulator>(recalibrated);
  simulator_->setWrench(kPayloadWrench);
  std::this_thread::sleep_for(milliseconds(200));
  stop_sensor_.store(false);
  sensor_thread_ = std::thread([this] { simulator_->serve(bus_->sensor_end, stop_sensor_); });
  ASSERT_TRUE(waitFor([&] { return driver->counters().resyncs == 2; }));
  EXPECT_FALSE(driver->biased());
  ASSERT_TRUE(waitSamples(3));
  EXPECT_EQ(driver->identity().calibration.matrix, recalibrated.calibration.matrix);
  const Vec6 error = latest().wrench_Sensor - kPayloadWrench;
  EXPECT_LT(error.head<3>().cwiseAbs().maxCoeff(), 0.2);   // N: a few gauge counts
  EXPECT_LT(error.tail<3>().cwiseAbs().maxCoeff(), 0.02);  // N·m
}

TEST_P(DriverTest, DroppedAndCorruptRepliesNeverGiveAWrongWrench) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  const auto expected = simulator_->gaugesFor(kPayloadWrench);
  const Vec6 exact = netcan::WrenchConverter(simulator_->options().calibration).wrench(expected, Vec6::Zero());
  ftsim::Faults faults;
  faults.drop_probability = 0.2;
  faults.corrupt_probability = 0.2;
  simulator_->setFaults(faults);
  int samples = 0, timeouts = 0;
  for (int k = 0; k < 300; ++k) {
    WrenchSample sample;
    const PollResult result = driver->pollOnce(in(milliseconds(5)), sink_, sample);
    if (result == PollResult::kSample) {
      ++samples;
      ASSERT_EQ(sample.wrench_Sensor, exact) << "poll " << k;
    } else {
      ASSERT_EQ(result, PollResult::kTimeout);
      ++timeouts;
    }
  }
  const FtSensorCounters c = driver->counters();
  const ftsim::SimulatorCounters s = simulator_->counters();
  EXPECT_EQ(samples + timeouts, 300);
  EXPECT_GT(samples, 100) << "0.6² of polls get both halves intact";
  EXPECT_GT(timeouts, 50);
  EXPECT_GT(s.dropped, 0);
  EXPECT_EQ(c.bad_length + c.unknown_opcode, s.corrupted) << "every corrupt frame counted";
}

TEST_P(DriverTest, GarbageFramesAreIgnoredAndCounted) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  WrenchSample reference;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, reference), PollResult::kSample);
  ftsim::Faults faults;
  faults.garbage_per_poll = 3;  // random ids and lengths before each reply frame
  simulator_->setFaults(faults);
  for (int k = 0; k < 50; ++k) {
    WrenchSample sample;
    ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
    ASSERT_EQ(sample.wrench_Sensor, reference.wrench_Sensor);
  }
  simulator_->setFaults({});
  // The sensor's own ids with a wrong length or an opcode without reply, as a faulty node sends.
  // None is a request the sensor acts on (on vcan it hears them too): no 0x0 of length 0, no
  // reset (0xC).
  uint8_t data[8] = {};
  constexpr uint8_t kNoReply[] = {0xA, 0xB, 0xD, 0xE};
  for (int k = 0; k < 10; ++k) {
    inject(netcan::makeFrame(0x20, Opcode::kGaugesSecond, data, uint8_t(k % 6)));
    inject(netcan::makeFrame(0x20, Opcode(kNoReply[k % 4]), data, 3));
  }
  WrenchSample sample;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  EXPECT_EQ(sample.wrench_Sensor, reference.wrench_Sensor);
  const FtSensorCounters c = driver->counters();
  const int64_t garbage = simulator_->counters().garbage;
  EXPECT_EQ(garbage, 50 * 2 * 3);
  if (bus_->kernel_filters) {
    EXPECT_EQ(c.foreign_id, 0) << "the CAN_RAW filter drops other ids in the kernel";
  } else {
    EXPECT_EQ(c.foreign_id, garbage);
  }
  EXPECT_EQ(c.bad_length, 10);
  EXPECT_EQ(c.unknown_opcode, 10);
}

TEST_P(DriverTest, HalvesInTheWrongOrderNeverPair) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  ftsim::Faults faults;
  faults.second_half_first = true;
  simulator_->setFaults(faults);
  WrenchSample sample;
  EXPECT_EQ(driver->pollOnce(in(milliseconds(30)), sink_, sample), PollResult::kTimeout);
  EXPECT_EQ(driver->counters().unpaired, 1);
  simulator_->setFaults({});
  EXPECT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample)
      << "the first half left pending by the previous poll is dropped, not paired";
}

TEST_P(DriverTest, CriticalStatusBitsMakeTheSampleUnusable) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  ftsim::Faults faults;
  faults.status_word = netcan::status_bit::kWatchdogReset | netcan::status_bit::kAnyError;
  simulator_->setFaults(faults);
  WrenchSample sample;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  EXPECT_EQ(sample.sensor_status, 0u) << "a watchdog reset is reported, the gauges stay valid";
  EXPECT_EQ(driver->counters().last_status_word, faults.status_word);
  Vec6 wrench;
  EXPECT_EQ(wrenchFor(sink_.slot, sample.stamp_ns + 1'000'000, 20'000'000, wrench), Status::kOk);

  faults.status_word = netcan::status_bit::kPowerSupplyTooLow | netcan::status_bit::kAnyError;
  simulator_->setFaults(faults);
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  EXPECT_EQ(sample.sensor_status, faults.status_word);
  EXPECT_EQ(wrenchFor(sink_.slot, steadyNowNs(), 20'000'000, wrench), Status::kStaleWrench);
  EXPECT_EQ(driver->counters().critical_status, 1);
}

TEST_P(DriverTest, BusOffStopsPollingUntilTheRestart) {
  startSensor();
  FtSensorOptions options;
  options.poll_hz = 500.0;
  options.bus_off_probe_ns = 10'000'000'000;  // no probes: only the restart notice recovers
  FtSensorDriver* const driver = makeDriver(options);
  simulator_->setWrench(kPayloadWrench);
  runDriver(*driver);
  ASSERT_TRUE(waitSamples(5));

  inject(ftsim::errorFrame(CAN_ERR_BUSOFF));
  // Waited for, not slept on: the driver publishes the bus-off sample as it reads the frame.
  ASSERT_TRUE(waitFor([&] { return latest().sensor_status == kSampleBusOff; }));
  const FtSensorCounters off = driver->counters();
  EXPECT_EQ(off.state, FtSensorState::kBusOff);
  EXPECT_EQ(off.bus_off, 1);
  Vec6 wrench;
  EXPECT_EQ(wrenchFor(sink_.slot, steadyNowNs(), 1'000'000'000, wrench), Status::kStaleWrench);
  std::this_thread::sleep_for(milliseconds(50));
  EXPECT_EQ(driver->counters().polls, off.polls) << "silent while bus-off";

  inject(ftsim::errorFrame(CAN_ERR_RESTARTED));
  ASSERT_TRUE(waitSamples(5));
  const FtSensorCounters on = driver->counters();
  EXPECT_EQ(on.state, FtSensorState::kRunning);
  EXPECT_EQ(on.restarts, 1);
  EXPECT_EQ(wrenchFor(sink_.slot, latest().stamp_ns + 1'000'000, 20'000'000, wrench), Status::kOk);
}

TEST_P(DriverTest, BusOffWithoutRestartNoticeRecoversByProbing) {
  startSensor();
  FtSensorOptions options;
  options.bus_off_probe_ns = 30'000'000;
  FtSensorDriver* const driver = makeDriver(options);
  runDriver(*driver);
  ASSERT_TRUE(waitSamples(3));
  inject(ftsim::errorFrame(CAN_ERR_BUSOFF | CAN_ERR_CRTL));
  ASSERT_TRUE(waitSamples(3));
  const FtSensorCounters c = driver->counters();
  EXPECT_EQ(c.bus_off, 1);
  EXPECT_EQ(c.restarts, 1);
  EXPECT_EQ(c.state, FtSensorState::kRunning);
}

TEST_P(DriverTest, ResetReadsTheCalibrationAgainAndDropsTheBias) {
  ftsim::SimulatorOptions sensor;
  sensor.reset_silence_ns = 50'000'000;
  startSensor(sensor);
  FtSensorOptions options;
  options.reset_silence_ns = 80'000'000;
  options.bias_samples = 1;
  FtSensorDriver* const driver = makeDriver(options);
  driver->requestBias();
  runDriver(*driver);
  ASSERT_TRUE(waitSamples(3));
  EXPECT_TRUE(driver->biased());
  driver->requestReset();
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (driver->counters().resets == 0 && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(milliseconds(5));
  }
  EXPECT_EQ(driver->counters().resets, 1);
  EXPECT_EQ(simulator_->counters().resets, 1);
  EXPECT_FALSE(driver->biased());
  ASSERT_TRUE(waitSamples(3));
  EXPECT_EQ(driver->counters().state, FtSensorState::kRunning);
}

TEST_P(DriverTest, PollingAllocatesNothing) {
  startSensor();
  FtSensorDriver* const driver = makeDriver();
  simulator_->setWrench(kPayloadWrench);
  WrenchSample sample;
  ASSERT_EQ(driver->pollOnce(in(milliseconds(500)), sink_, sample), PollResult::kSample);
  long allocations = 0;
  {
    test::AllocationCounter counter;
    for (int k = 0; k < 200; ++k) driver->pollOnce(in(milliseconds(500)), sink_, sample);
    allocations = counter.count();
  }
  EXPECT_EQ(allocations, 0);
  EXPECT_EQ(driver->counters().samples, 201);
}

INSTANTIATE_TEST_SUITE_P(Bus, DriverTest, testing::Values("socketpair", "vcan"),
                         [](const testing::TestParamInfo<std::string>& info) {
                           return info.param == "vcan" ? std::string("Vcan") : std::string("Socketpair");
                         });

}  // namespace
