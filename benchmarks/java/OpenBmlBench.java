// Parse-and-serialise throughput of the Java reference parser of the BML
// community (saiba/OpenBMLParser), measured for `realizer bench parser`.
//
// Usage: java -cp <OpenBMLParser classes and jars>:<this class> OpenBmlBench SECONDS FILE...
// For each file: BehaviourBlock.readXML(text) then toXMLString(), as the
// realizer's bench does parse_bml + serialise. Files the reference refuses
// are left out (reported). After a warm-up that lets the JIT compile the
// hot paths, the set is parsed again and again for SECONDS; the best of
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
        long warmEnd = System.nanoTime() + (long) (Math.max(1.0, seconds / 2) * 1e9);
        while (System.nanoTime() < warmEnd) {
            pass(documents);
        }
        double best = Double.MAX_VALUE;
        int rounds = 0;
        long end = System.nanoTime() + (long) (seconds * 1e9);
        while (System.nanoTime() < end || rounds < 3) {
            int passes = 0;
            long start = System.nanoTime();
            long stop = start + 50_000_000L; // rounds of at least 50 ms
            long now;
            do {
                pass(documents);
                passes++;
                now = System.nanoTime();
            } while (now < stop);
            best = Math.min(best, (now - start) / 1e9 / passes);
            rounds++;
        }
        System.out.println("{\"documents\": " + documents.size() + ", \"accepted\": [" + accepted
                + "], \"refused\": [" + refused + "], \"seconds_per_pass\": " + best
                + ", \"rounds\": " + rounds + ", \"sink\": " + (sink & 1) + "}");
    }
}
