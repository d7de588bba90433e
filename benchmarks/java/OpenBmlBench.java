// Parse-and-serialise throughput of the Java reference parser of the BML
// community (saiba/OpenBMLParser), measured for `realizer bench parser`.
//
// Usage: java -cp <OpenBMLParser classes and jars>:<this class> OpenBmlBench SECONDS FILE...
// For each file: BehaviourBlock.readXML(text) then toXMLString(), as the
// realizer's bench does parse_bml + serialise. Files the reference refuses
// are left out (reported). After a warm-up of SECONDS/2 (at least 1) of the
// JVM's CPU time, which lets the JIT compile the hot paths even on a busy
// machine, the set is parsed again and again for SECONDS; the best of
// several rounds is printed as one JSON line:
// {"documents": n, "refused": [...], "seconds_per_pass": s, "rounds": r}
import java.nio.charset.StandardCharsets;
import java.nio.file.Files;
import java.nio.file.Paths;
import java.util.ArrayList;
import java.util.List;

import saiba.bml.core.BehaviourBlock;

public final class OpenBmlBench {
    private static int sink = 0;

    private static void pass(List<String> documents) {
        for (String text : documents) {
            BehaviourBlock block = new BehaviourBlock();
            block.readXML(text);
            sink += block.toXMLString().length();
        }
    }

    /** CPU time of the whole JVM (JIT and collector threads included), or wall time. */
    private static long processCpuNanos() {
        java.lang.management.OperatingSystemMXBean bean =
                java.lang.management.ManagementFactory.getOperatingSystemMXBean();
        if (bean instanceof com.sun.management.OperatingSystemMXBean) {
            long cpu = ((com.sun.management.OperatingSystemMXBean) bean).getProcessCpuTime();
            if (cpu >= 0) {
                return cpu;
            }
        }
        return System.nanoTime();
    }

    public static void main(String[] args) throws Exception {
        double seconds = Double.parseDouble(args[0]);
        List<String> documents = new ArrayList<>();
        StringBuilder refused = new StringBuilder();
        StringBuilder accepted = new StringBuilder();
        for (int i = 1; i < args.length; i++) {
            String text = new String(Files.readAllBytes(Paths.get(args[i])), StandardCharsets.UTF_8);
            try {
                BehaviourBlock block = new BehaviourBlock();
                block.readXML(text);
                block.toXMLString();
                documents.add(text);
                accepted.append(accepted.length() > 0 ? "," : "").append(i - 1);
            } catch (Throwable error) {
                refused.append(refused.length() > 0 ? "," : "").append(i - 1);
            }
        }
        // Warm up for CPU time, not wall time: on a busy machine a second of
        // wall time may give the JIT compiler threads too little CPU to
        // compile the hot paths, and the passes would be timed half
        // interpreted. Bounded by a minute of wall time.
        long warmCpu = (long) (Math.max(1.0, seconds / 2) * 1e9);
        long cpuStart = processCpuNanos();
        long wallLimit = System.nanoTime() + 60_000_000_000L;
        while (processCpuNanos() - cpuStart < warmCpu && System.nanoTime() < wallLimit) {
            pass(documents);
        }
        java.lang.management.ThreadMXBean threads =
                java.lang.management.ManagementFactory.getThreadMXBean();
        double best = Double.MAX_VALUE;
        double bestCpu = Double.MAX_VALUE;
        int rounds = 0;
        long end = System.nanoTime() + (long) (seconds * 1e9);
        while (System.nanoTime() < end || rounds < 3) {
            int passes = 0;
            long start = System.nanoTime();
            long roundCpu = threads.getCurrentThreadCpuTime();
            long stop = start + 50_000_000L; // rounds of at least 50 ms
            long now;
            do {
                pass(documents);
                passes++;
                now = System.nanoTime();
            } while (now < stop);
            long cpu = threads.getCurrentThreadCpuTime() - roundCpu;
            best = Math.min(best, (now - start) / 1e9 / passes);
            bestCpu = Math.min(bestCpu, cpu / 1e9 / passes);
            rounds++;
        }
        // cpu_seconds_per_pass: this thread's CPU time, without the
        // collector's and the JIT's threads (which favours the reference)
        System.out.println("{\"documents\": " + documents.size() + ", \"accepted\": [" + accepted
                + "], \"refused\": [" + refused + "], \"seconds_per_pass\": " + best
                + ", \"cpu_seconds_per_pass\": " + bestCpu
                + ", \"rounds\": " + rounds + ", \"sink\": " + (sink & 1) + "}");
    }
}
