// Decodes every event of an LCM log the way lcm-spy does: look the type up by
// the fingerprint in the message's first 8 bytes in lcm-spy's own type
// database (built from the classpath), then construct it from the bytes.
// Prints one row per channel and exits 1 if any channel does not decode.
//
//   java -cp vslam_lcmtypes_java.jar:lcm.jar scripts/lib/SpyDecodeCheck.java LOG
import java.io.ByteArrayInputStream;
import java.io.DataInputStream;
import java.io.EOFException;
import java.util.Map;
import java.util.TreeMap;

public class SpyDecodeCheck {
  static final class Row {
    String type = "?";
    long decoded = 0;
    long failed = 0;
    String error = "";
  }

  public static void main(String[] args) throws Exception {
    if (args.length != 1) {
      System.err.println("usage: SpyDecodeCheck LOG");
      System.exit(2);
    }
    lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
    lcm.logging.Log log = new lcm.logging.Log(args[0], "r");
    Map<String, Row> rows = new TreeMap<>();
    while (true) {
      lcm.logging.Log.Event ev;
      try {
        ev = log.readNext();
      } catch (EOFException e) {
        break;
      }
      if (ev == null) break;
      Row row = rows.computeIfAbsent(ev.channel, c -> new Row());
      try {
        DataInputStream in = new DataInputStream(new ByteArrayInputStream(ev.data));
        long fingerprint = in.readLong();
        Class<?> cls = db.getClassByFingerprint(fingerprint);
        if (cls == null) throw new Exception(String.format("no type with fingerprint %016x", fingerprint));
        row.type = cls.getName();
        cls.getConstructor(byte[].class).newInstance((Object) ev.data);
        row.decoded++;
      } catch (Exception e) {
        row.failed++;
        Throwable cause = e.getCause() != null ? e.getCause() : e;
        row.error = cause.toString();
      }
    }
    log.close();
    int bad = 0;
    System.out.printf("%-30s %-36s %10s %8s%n", "channel", "type (as lcm-spy shows it)", "decoded", "failed");
    for (Map.Entry<String, Row> e : rows.entrySet()) {
      Row r = e.getValue();
      System.out.printf("%-30s %-36s %10d %8d %s%n", e.getKey(), r.type, r.decoded, r.failed, r.error);
      if (r.failed > 0) bad++;
    }
    System.out.printf("%d channels, %d that lcm-spy cannot decode%n", rows.size(), bad);
    System.exit(bad == 0 ? 0 : 1);
  }
}
