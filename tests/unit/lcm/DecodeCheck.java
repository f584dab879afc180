// Java half of the interop test: decodes the messages lcm_types_test (JavaInterop) encoded in
// C++, the way lcm-spy does. The fingerprint at the head of each file must lead
// lcm.spy.LCMTypeDatabase (which scans the class path with lcm.util.ClassDiscoverer) to our
// class inside inertia_lcm_types.jar, loaded beside Debian's lcm.jar; every field must equal
// the values in known_messages.hpp. Prints one line per message; exit 1 on the first mismatch.
//
// Usage: java -cp lcm.jar:inertia_lcm_types.jar:<dir of DecodeCheck.class> DecodeCheck DIR

import java.io.File;
import java.nio.ByteBuffer;
import java.nio.file.Files;
import java.util.Arrays;

public class DecodeCheck {
    private static int failures = 0;

    private static void check(String what, Object got, Object want) {
        boolean same = (got == null) ? want == null : got.equals(want);
        if (!same) {
            System.err.println("MISMATCH " + what + ": got " + got + ", want " + want);
            failures++;
        }
    }

    private static void checkArray(String what, Object got, Object want) {
        boolean same = Arrays.deepEquals(new Object[] {got}, new Object[] {want});
        if (!same) {
            System.err.println("MISMATCH " + what + ": got " + Arrays.deepToString(new Object[] {got})
                               + ", want " + Arrays.deepToString(new Object[] {want}));
            failures++;
        }
    }

    // Finds the class by the fingerprint the C++ encoder wrote, as lcm-spy does, checks that it
    // came from our jar, and decodes the message with it.
    private static Object decode(lcm.spy.LCMTypeDatabase db, File dir, String typeName) throws Exception {
        byte[] bytes = Files.readAllBytes(new File(dir, typeName + ".bin").toPath());
        long fingerprint = ByteBuffer.wrap(bytes, 0, 8).getLong();
        Class<?> cls = db.getClassByFingerprint(fingerprint);
        if (cls == null) {
            throw new AssertionError(String.format(
                "LCMTypeDatabase knows no class with fingerprint 0x%016x (%s.bin)", fingerprint, typeName));
        }
        check(typeName + " class", cls.getName(), "inertia." + typeName);
        check(typeName + " LCM_FINGERPRINT", cls.getField("LCM_FINGERPRINT").getLong(null), fingerprint);
        String origin = cls.getProtectionDomain().getCodeSource().getLocation().getPath();
        check(typeName + " loaded from inertia_lcm_types.jar", origin.endsWith("/inertia_lcm_types.jar"), true);
        Object msg = cls.getConstructor(byte[].class).newInstance((Object) bytes);
        System.out.println(String.format("decoded %s fingerprint=0x%016x bytes=%d from %s",
                                         cls.getName(), fingerprint, bytes.length, origin));
        return msg;
    }

    private static void checkSampleBlock(inertia.sample_block_t m) {
        check("device", m.device, "sim_ref_1");
        check("seq", m.seq, 42L);
        check("t0_mono_ns", m.t0_mono_ns, 123456789012L);
        check("t0_utime", m.t0_utime, 1700000000123456L);
        check("sample_period_s", m.sample_period_s, 0.001);
        check("num_channels", m.num_channels, 3);
        checkArray("channel_ids", m.channel_ids, new int[] {10, 11, 12});
        checkArray("channel_names", m.channel_names, new String[] {"a_x", "a_y", "temp"});
        checkArray("units", m.units, new String[] {"m/s^2", "m/s^2", "degC"});
        checkArray("channel_seq", m.channel_seq, new long[] {1000, 1000, 250});
        check("num_samples", m.num_samples, 10);
        for (int c = 0; c < 3; c++) {
            for (int s = 0; s < 10; s++) {
                check("values[" + c + "][" + s + "]", m.values[c][s], 100.0 * c + 0.25 * s - 1.5);
                boolean valid = ((m.valid[c][s / 8] >> (s % 8)) & 1) == 1;
                check("valid[" + c + "][" + s + "]", valid, !((c == 1 && s == 3) || (c == 2 && s == 9)));
            }
        }
        check("valid_bytes", m.valid_bytes, 2);
    }

    private static void checkDaqStatus(inertia.daq_status_t m) {
        check("utime", m.utime, 1700000000000000L);
        check("mono_ns", m.mono_ns, 5000000000L);
        check("uptime_s", m.uptime_s, 3600.5);
        check("num_devices", m.num_devices, 2);
        inertia.device_status_t d0 = m.devices[0];
        check("devices[0].device", d0.device, "can0_ref");
        check("devices[0].state", d0.state, inertia.device_status_t.STATE_ACTIVE);
        check("devices[0].sample_rate_hz", d0.sample_rate_hz, 999.5);
        check("devices[0].samples", d0.samples, 3598200L);
        check("devices[0].ring_drops", d0.ring_drops, 3L);
        check("devices[0].ring_high_water", d0.ring_high_water, 17);
        check("devices[0].ring_capacity", d0.ring_capacity, 1024);
        check("devices[0].decode_errors", d0.decode_errors, 2L);
        check("devices[0].read_time_max_us", d0.read_time_max_us, 42.5);
        check("devices[0].num_faults", d0.num_faults, 0);
        check("devices[0].counter_resets", d0.counter_resets, 2L);
        check("devices[0].encoder_overflows", d0.encoder_overflows, 11L);
        inertia.device_status_t d1 = m.devices[1];
        check("devices[1].device", d1.device, "modbus_thermal");
        check("devices[1].state", d1.state, inertia.device_status_t.STATE_FAILED);
        check("devices[1].read_time_max_us", d1.read_time_max_us, 1500.25);
        checkArray("devices[1].faults", d1.faults, new String[] {"modbus-gone"});
        check("lcm_messages", m.lcm_messages, 40000L);
        check("lcm_publish_failures", m.lcm_publish_failures, 1L);
        check("log_path", m.log_path, "/var/lib/inertia/log/run-001.lcmlog");
        check("log_bytes", m.log_bytes, 123456789L);
        check("log_rotations", m.log_rotations, 2);
        check("log_fsync_last_ms", m.log_fsync_last_ms, 1.5);
        check("log_fsync_max_ms", m.log_fsync_max_ms, 12.25);
        checkArray("faults", m.faults, new String[] {"disk-slow"});
    }

    private static void checkPlanEvent(inertia.plan_event_t m) {
        check("utime", m.utime, 1700000001000000L);
        check("mono_ns", m.mono_ns, 6000000000L);
        check("mark", m.mark, inertia.plan_event_t.MARK_PHASE_START);
        check("case_name", m.case_name, "shaker-ia");
        check("kind", m.kind, "shaker");
        check("phase", m.phase, "sine");
        check("phase_index", m.phase_index, 2);
        check("start_mono_ns", m.start_mono_ns, 6000000000L);
        check("end_mono_ns", m.end_mono_ns, 36000000000L);
        checkArray("setpoint_names", m.setpoint_names, new String[] {"frequency", "amplitude"});
        checkArray("setpoint_values", m.setpoint_values, new double[] {80.0, 19.6133});
        checkArray("setpoint_units", m.setpoint_units, new String[] {"Hz", "m/s^2"});
    }

    private static void checkModelEstimate(inertia.model_estimate_t m) {
        check("utime", m.utime, 1700000002000000L);
        check("mono_ns", m.mono_ns, 7000000000L);
        check("sensor", m.sensor, "sut_accel_1");
        check("output_unit", m.output_unit, "mA");
        check("num_terms", m.num_terms, 4);
        checkArray("terms", m.terms, new String[] {"1", "a_i", "a_i^2", "a_i*abs(a_i)"});
        checkArray("values", m.values, new double[] {3.44e-3, 0.0877, 1.5e-5, -2.0e-6});
        checkArray("std_devs", m.std_devs, new double[] {1.0e-6, 2.0e-6, 3.0e-7, 4.0e-7});
        check("residual_variance", m.residual_variance, 1.0e-8);
        checkArray("misalignment_rad", m.misalignment_rad, new double[] {1.0e-3, -2.0e-3, 5.0e-4});
        check("samples_used", m.samples_used, 200000L);
        check("converged", m.converged, true);
        checkArray("t_values", m.t_values, new double[] {3440.0, 43850.0, 50.0, -5.0});
        check("cases_used", m.cases_used, 4);
        check("noise_ar_order", m.noise_ar_order, 12);
        check("square_corner_rad_s", m.square_corner_rad_s, 502.2);
        check("num_mountings", m.num_mountings, 2);
        checkArray("mountings", m.mountings, new String[] {"rotation-table", "shaker-fixture"});
        check("mounting_determined[1]", m.mounting_determined[1], false);
        check("mounting_angles_rad[1][2]", m.mounting_angles_rad[1][2], -2.2e-2);
        check("mounting_angles_rad[0][0] is NaN", Double.isNaN(m.mounting_angles_rad[0][0]), true);
        check("mounting_samples[0]", m.mounting_samples[0], 370000L);
    }

    private static void checkStructureTable(inertia.structure_table_t m) {
        check("sensor", m.sensor, "sut_accel_1");
        check("num_candidates", m.num_candidates, 2);
        checkArray("terms", m.terms, new String[] {"a_i*abs(a_i)", "a_i[k-1]"});
        checkArray("effects", m.effects, new String[] {"odd quadratic", "dynamics"});
        checkArray("t_values", m.t_values, new double[] {20.0, -0.33});
        check("significant[0]", m.significant[0], true);
    }

    private static void checkAnalyzerStatus(inertia.analyzer_status_t m) {
        check("bench", m.bench, "sim-paper");
        check("received", m.received, 3303L);
        check("skipped_malformed", m.skipped_malformed, 2L);
        check("queue_drops", m.queue_drops, 8L);
        check("latency_p99_ms", m.latency_p99_ms, 95.0);
        checkArray("sensors", m.sensors, new String[] {"acc1"});
        checkArray("notes", m.notes, new String[] {"INERTIA_RAW_ACCEL: valid_bytes 3 for 40 samples"});
    }

    public static void main(String[] args) throws Exception {
        if (args.length != 1) {
            System.err.println("usage: DecodeCheck DIR");
            System.exit(2);
        }
        File dir = new File(args[0]);
        lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
        checkSampleBlock((inertia.sample_block_t) decode(db, dir, "sample_block_t"));
        checkDaqStatus((inertia.daq_status_t) decode(db, dir, "daq_status_t"));
        checkPlanEvent((inertia.plan_event_t) decode(db, dir, "plan_event_t"));
        checkModelEstimate((inertia.model_estimate_t) decode(db, dir, "model_estimate_t"));
        checkStructureTable((inertia.structure_table_t) decode(db, dir, "structure_table_t"));
        checkAnalyzerStatus((inertia.analyzer_status_t) decode(db, dir, "analyzer_status_t"));
        if (failures > 0) {
            System.err.println(failures + " field(s) differ");
            System.exit(1);
        }
        System.out.println("all fields match");
    }
}
