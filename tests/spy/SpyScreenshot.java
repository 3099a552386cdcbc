// Screenshot of the real lcm-spy showing a camera channel in the image view
// (docs/img/lcm-spy-image.png); run by spy_screenshot.sh under Xvfb.
//   java -cp TYPES_JAR:lcm.jar:jchart2d.jar SpyScreenshot.java URL CHANNEL OUT.png
// Starts lcm.spy.Spy in this JVM, waits for CHANNEL in its table, then
// double-clicks the row with java.awt.Robot (real X input events through the
// XTEST extension: lcm-spy's own mouse handler opens the plugin), waits for
// frames in the view, places the two windows side by side (there is no window
// manager under Xvfb) and captures the screen.
import java.awt.Component;
import java.awt.Container;
import java.awt.Point;
import java.awt.Rectangle;
import java.awt.Robot;
import java.awt.Toolkit;
import java.awt.Window;
import java.awt.event.InputEvent;
import java.awt.image.BufferedImage;
import java.io.File;
import java.util.concurrent.atomic.AtomicReference;
import javax.imageio.ImageIO;
import javax.swing.JFrame;
import javax.swing.JTable;
import javax.swing.SwingUtilities;
import vslam.spy.ImagePanel;

public class SpyScreenshot {
    static <T> T find(Component c, Class<T> type) {
        if (type.isInstance(c)) return type.cast(c);
        if (c instanceof Container) {
            for (Component child : ((Container) c).getComponents()) {
                T found = find(child, type);
                if (found != null) return found;
            }
        }
        return null;
    }

    static <T> T findInWindows(Class<T> type) {
        for (Window w : Window.getWindows()) {
            if (!w.isShowing()) continue;
            T found = find(w, type);
            if (found != null) return found;
        }
        return null;
    }

    /** Polls until the condition holds on the EDT, or exits 1 naming what did not happen. */
    interface Probe { Object get(); }
    static Object await(String what, Probe probe) throws Exception {
        for (int i = 0; i < 300; ++i) {
            AtomicReference<Object> result = new AtomicReference<>();
            SwingUtilities.invokeAndWait(() -> result.set(probe.get()));
            if (result.get() != null) return result.get();
            Thread.sleep(100);
        }
        System.err.println("spy-screenshot: " + what + " did not happen in 30 s");
        System.exit(1);
        return null;
    }

    public static void main(String[] args) throws Exception {
        String url = args[0], channel = args[1];
        File out = new File(args[2]);
        lcm.spy.Spy.main(new String[] {"--lcm-url=" + url});

        Point row = (Point) await("channel " + channel + " in lcm-spy's table", () -> {
            JTable table = findInWindows(JTable.class);
            if (table == null) return null;
            for (int r = 0; r < table.getRowCount(); ++r) {
                if (channel.equals(String.valueOf(table.getValueAt(r, 0)))) {
                    Rectangle cell = table.getCellRect(r, 0, true);
                    Point p = new Point((int) cell.getCenterX(), (int) cell.getCenterY());
                    SwingUtilities.convertPointToScreen(p, table);
                    return p;
                }
            }
            return null;
        });
        Robot robot = new Robot();
        robot.setAutoDelay(40);
        robot.mouseMove(row.x, row.y);
        for (int i = 0; i < 2; ++i) {
            robot.mousePress(InputEvent.BUTTON1_DOWN_MASK);
            robot.mouseRelease(InputEvent.BUTTON1_DOWN_MASK);
        }
        ImagePanel panel = (ImagePanel) await("a frame in the image view", () -> {
            ImagePanel p = findInWindows(ImagePanel.class);
            return p != null && p.picture() != null ? p : null;
        });
        System.out.println("spy-screenshot: view shows " + panel.caption());

        // Spy's table on the left, the image view (its own window) on the right.
        SwingUtilities.invokeAndWait(() -> {
            JFrame view = (JFrame) SwingUtilities.getWindowAncestor(panel);
            Window spy = SwingUtilities.getWindowAncestor(findInWindows(JTable.class));
            spy.setBounds(0, 0, 560, 400);
            view.setBounds(560, 0, 500, 400);
        });
        Thread.sleep(1500);  // a few more frames and a repaint of both windows
        Rectangle screen = new Rectangle(0, 0, 1060, 400);
        BufferedImage shot = robot.createScreenCapture(screen);
        ImageIO.write(shot, "png", out);
        System.out.println("spy-screenshot: wrote " + out + " (" + Toolkit.getDefaultToolkit().getScreenSize() + ")");
        System.exit(0);
    }
}
