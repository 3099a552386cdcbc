// Checks an LCM log for lcm-spy: every event must be a whole LCM log event,
// and every payload must decode as the type its fingerprint names in
// lcm-spy's own type database (built from the classpath), with no bytes left
// over (the bus rejects those too). Prints one row per channel, then every
// problem with its byte offset and event number.
//
// Events on LCM_SELF_TEST are LCM's own (lcm-logger records the self-test
// the UDP provider sends to itself at start-up): they are counted and listed
// apart, not decoded.
//
// The file is read here rather than with lcm.logging.Log, which skips bytes
// until it finds a sync word (so a garbled stretch vanishes without a word)
// and throws EOFException for a file that ends inside an event (which reads
// like a clean end of file). After damage the check resynchronises on the next
// plausible event and goes on, so one bad stretch does not hide the rest.
//
//   java -cp vslam_lcmtypes_java.jar:lcm.jar scripts/lib/SpyDecodeCheck.java LOG
//
// Exit status: 0 if the log is whole and every channel decodes, 1 if not,
// 2 if the log cannot be read at all.
import java.io.DataInput;
import java.io.IOException;
import java.lang.reflect.InvocationTargetException;
import java.nio.ByteBuffer;
import java.nio.channels.FileChannel;
import java.nio.charset.StandardCharsets;
import java.nio.file.Path;
import java.nio.file.StandardOpenOption;
import java.util.ArrayList;
import java.util.List;
import java.util.Map;
import java.util.TreeMap;

public class SpyDecodeCheck {
  static final String SELF_TEST_CHANNEL = "LCM_SELF_TEST";
  static final int MAX_PROBLEMS_SHOWN = 20;

  static final class Row {
    String type = "?";
    long decoded = 0;
    long failed = 0;
    String error = "";
  }

  public static void main(String[] args) {
    if (args.length != 1) {
      System.err.println("usage: SpyDecodeCheck LOG");
      System.exit(2);
    }
    try (LogReader log = new LogReader(Path.of(args[0]))) {
      System.exit(check(log));
    } catch (IOException e) {
      System.err.println("spy --check: cannot read " + args[0] + ": " + e);
      System.exit(2);
    }
  }

  static int check(LogReader log) throws IOException {
    lcm.spy.LCMTypeDatabase db = new lcm.spy.LCMTypeDatabase();
    Map<String, Row> rows = new TreeMap<>();
    List<String> problems = new ArrayList<>();
    long selfTestEvents = 0;
    LogReader.Event ev;
    while ((ev = log.next(problems)) != null) {
      if (ev.channel.equals(SELF_TEST_CHANNEL)) {
        ++selfTestEvents;
        continue;
      }
      Row row = rows.computeIfAbsent(ev.channel, c -> new Row());
      String error = decode(db, ev.data, row);
      if (error == null) {
        row.decoded++;
        continue;
      }
      String where = String.format("event #%d (eventnum %d, byte %d) on %s", ev.index, ev.eventNumber,
                                   ev.offset, ev.channel);
      if (row.failed++ == 0) row.error = where + ": " + error;
      problems.add(where + ": " + error);
    }

    int bad = 0;
    System.out.printf("%-30s %-36s %10s %8s%n", "channel", "type (as lcm-spy shows it)", "decoded", "failed");
    for (Map.Entry<String, Row> e : rows.entrySet()) {
      Row r = e.getValue();
      System.out.printf("%-30s %-36s %10d %8d %s%n", e.getKey(), r.type, r.decoded, r.failed, r.error);
      if (r.failed > 0) bad++;
    }
    System.out.printf("%d channels, %d that lcm-spy cannot decode%n", rows.size(), bad);
    if (selfTestEvents > 0) {
      System.out.printf("LCM self-test: %d events on %s (LCM's own, not decoded)%n", selfTestEvents,
                        SELF_TEST_CHANNEL);
    }
    if (problems.isEmpty()) {
      System.out.printf("log OK: %d events, %d bytes%n", log.eventsRead(), log.size());
      return 0;
    }
    System.err.printf("spy --check: %s: %d problem%s%n", log.path(), problems.size(),
                      problems.size() == 1 ? "" : "s");
    for (int i = 0; i < problems.size() && i < MAX_PROBLEMS_SHOWN; ++i) {
      System.err.println("  " + problems.get(i));
    }
    if (problems.size() > MAX_PROBLEMS_SHOWN) {
      System.err.printf("  ... and %d more%n", problems.size() - MAX_PROBLEMS_SHOWN);
    }
    return 1;
  }

  // Decodes data as lcm-spy would; returns null if it is exactly one message
  // of the type its fingerprint names, else why not.
  static String decode(lcm.spy.LCMTypeDatabase db, byte[] data, Row row) {
    if (data.length < 8) {
      return String.format("payload of %d bytes is too short for a type fingerprint", data.length);
    }
    long fingerprint = ByteBuffer.wrap(data).getLong();
    Class<?> cls = db.getClassByFingerprint(fingerprint);
    if (cls == null) return String.format("no type with fingerprint %016x", fingerprint);
    row.type = cls.getName();
    lcm.lcm.LCMDataInputStream in = new lcm.lcm.LCMDataInputStream(data);
    try {
      cls.getConstructor(DataInput.class).newInstance(in);
    } catch (InvocationTargetException e) {
      return String.format("payload of %d bytes does not decode as %s: %s", data.length, cls.getName(),
                           e.getCause());
    } catch (ReflectiveOperationException e) {
      return "cannot construct " + cls.getName() + ": " + e;
    } catch (OutOfMemoryError e) {
      // A hostile array count; the decoder allocates before it reads.
      return String.format("payload of %d bytes does not decode as %s: %s", data.length, cls.getName(), e);
    }
    if (in.available() > 0) {
      return String.format("payload of %d bytes decodes as %s with %d bytes left over", data.length,
                           cls.getName(), in.available());
    }
    return null;
  }

  // Reads LCM log events: sync word 0xEDA1DA01 (big-endian uint32), event
  // number int64, timestamp int64, channel length int32, data length int32,
  // channel bytes, data bytes. Anything else is reported as a problem.
  static final class LogReader implements AutoCloseable {
    static final int SYNC = 0xEDA1DA01;
    static final int HEADER_BYTES = 28;
    static final int MAX_CHANNEL_BYTES = 255;  // as lcm.logging.Log

    static final class Event {
      long index;  // 1-based position in the file
      long offset;
      long eventNumber;
      long utime;
      String channel;
      byte[] data;
      long length;  // header, channel and payload bytes
    }

    private final Path path;
    private final FileChannel file;
    private final long size;
    private long pos = 0;
    private long eventsRead = 0;
    private long lastEventNumber = Long.MIN_VALUE;

    LogReader(Path path) throws IOException {
      this.path = path;
      this.file = FileChannel.open(path, StandardOpenOption.READ);
      this.size = file.size();
    }

    Path path() { return path; }
    long size() { return size; }
    long eventsRead() { return eventsRead; }

    @Override
    public void close() throws IOException { file.close(); }

    // The next whole event, or null at the end of the file. Damage found on
    // the way is added to problems, and reading resumes at the next event.
    Event next(List<String> problems) throws IOException {
      while (pos < size) {
        long index = eventsRead + 1;
        String problem = null;
        Event ev = null;
        if (size - pos < HEADER_BYTES) {
          problem = String.format("byte %d: file ends inside the header of event #%d (%d of %d header bytes)",
                                  pos, index, size - pos, HEADER_BYTES);
        } else {
          ByteBuffer h = read(pos, HEADER_BYTES);
          int sync = h.getInt();
          long eventNumber = h.getLong();
          long utime = h.getLong();
          int channelLen = h.getInt();
          int dataLen = h.getInt();
          long end = pos + HEADER_BYTES + (long) channelLen + (long) dataLen;
          if (sync != SYNC) {
            problem = String.format("byte %d: no LCM log event where event #%d should start (sync word 0x%08X, "
                                    + "expected 0x%08X)", pos, index, sync, SYNC);
          } else if (channelLen <= 0 || channelLen > MAX_CHANNEL_BYTES || dataLen < 0) {
            problem = String.format("byte %d: header of event #%d is not valid (channel length %d, payload "
                                    + "length %d)", pos, index, channelLen, dataLen);
          } else if (end > size) {
            String channel = size - pos - HEADER_BYTES >= channelLen ? " on " + channelAt(pos, channelLen) : "";
            problem = String.format("byte %d: file ends inside event #%d (eventnum %d%s): it needs %d bytes, "
                                    + "%d remain", pos, index, eventNumber, channel, end - pos, size - pos);
          } else {
            ev = new Event();
            ev.index = index;
            ev.offset = pos;
            ev.eventNumber = eventNumber;
            ev.utime = utime;
            ev.channel = channelAt(pos, channelLen);
            ByteBuffer d = read(pos + HEADER_BYTES + channelLen, dataLen);
            ev.data = new byte[dataLen];
            d.get(ev.data);
            ev.length = end - pos;
          }
        }
        if (ev != null) {
          ++eventsRead;
          lastEventNumber = ev.eventNumber;
          pos += ev.length;
          return ev;
        }
        long resume = findNextEvent(pos + 1);
        if (resume < 0) {
          problems.add(problem + "; no whole event follows, the last " + (size - pos) + " bytes are lost");
          pos = size;
          break;
        }
        String lost = "";
        if (lastEventNumber != Long.MIN_VALUE) {
          long resumeNumber = read(resume + 4, 8).getLong();
          if (resumeNumber > lastEventNumber + 1) {
            lost = String.format(" (eventnum jumps from %d to %d)", lastEventNumber, resumeNumber);
          }
        }
        problems.add(String.format("%s; skipped %d bytes to the next event at byte %d%s", problem, resume - pos,
                                   resume, lost));
        pos = resume;
      }
      return null;
    }

    // The offset of the first plausible event at or after from: a sync word,
    // valid lengths, and the event ends at the end of the file or at another
    // sync word (so a sync word inside a payload is not taken for an event).
    private long findNextEvent(long from) throws IOException {
      final int chunk = 1 << 16;
      for (long start = from; start + 4 <= size; start += chunk) {
        int n = (int) Math.min(chunk + 3, size - start);
        ByteBuffer b = read(start, n);
        for (int i = 0; i + 4 <= n; ++i) {
          if (b.getInt(i) == SYNC && plausibleEventAt(start + i)) return start + i;
        }
      }
      return -1;
    }

    private boolean plausibleEventAt(long at) throws IOException {
      if (size - at < HEADER_BYTES) return false;
      ByteBuffer h = read(at, HEADER_BYTES);
      int channelLen = h.getInt(20);
      int dataLen = h.getInt(24);
      if (channelLen <= 0 || channelLen > MAX_CHANNEL_BYTES || dataLen < 0) return false;
      long end = at + HEADER_BYTES + (long) channelLen + (long) dataLen;
      if (end == size) return true;
      return end + 4 <= size && read(end, 4).getInt() == SYNC;
    }

    private String channelAt(long eventOffset, int channelLen) throws IOException {
      ByteBuffer c = read(eventOffset + HEADER_BYTES, channelLen);
      byte[] bytes = new byte[channelLen];
      c.get(bytes);
      return new String(bytes, StandardCharsets.UTF_8);
    }

    private ByteBuffer read(long at, int n) throws IOException {
      ByteBuffer b = ByteBuffer.allocate(n);
      while (b.hasRemaining()) {
        if (file.read(b, at + b.position()) < 0) throw new IOException("unexpected end of file at byte " + at);
      }
      b.flip();
      return b;
    }
  }
}
