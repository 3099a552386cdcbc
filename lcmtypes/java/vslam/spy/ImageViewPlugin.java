package vslam.spy;

import java.awt.BorderLayout;
import java.awt.Window;
import java.awt.event.ActionEvent;
import java.beans.PropertyVetoException;
import javax.swing.AbstractAction;
import javax.swing.Action;
import javax.swing.JDesktopPane;
import javax.swing.JInternalFrame;
import javax.swing.SwingUtilities;
import javax.swing.Timer;
import javax.swing.event.InternalFrameAdapter;
import javax.swing.event.InternalFrameEvent;
import lcm.spy.ChannelData;
import lcm.spy.SpyPlugin;
import vslam.image_t;

/**
 * lcm-spy plugin: right-click a channel of type vslam.image_t and choose
 * "Image view" to see its frames as pictures.
 *
 * lcm-spy finds this class on its classpath (it is in the types jar), asks
 * canHandle for each channel's fingerprint, and on the menu choice opens a
 * window with a desktop pane and runs getAction(desktop, channel). lcm-spy
 * keeps its LCM instance to itself but decodes every message of the channel
 * into channel.last, so the view polls that field instead of subscribing
 * again (a second subscriber would need the bus URL, which the plugin is not
 * told).
 */
public class ImageViewPlugin implements SpyPlugin {
    /** Polling period: above camera rates, cheap when nothing changed. */
    static final int REFRESH_MS = 40;

    @Override
    public boolean canHandle(long fingerprint) {
        return fingerprint == image_t.LCM_FINGERPRINT;
    }

    @Override
    public Action getAction(JDesktopPane desktop, ChannelData channel) {
        // lcm-spy calls this with nulls once, only to read the action's name.
        return new AbstractAction("Image view") {
            private static final long serialVersionUID = 1L;

            @Override
            public void actionPerformed(ActionEvent e) {
                if (desktop != null && channel != null) open(desktop, channel);
            }
        };
    }

    /** Adds a view of channel to desktop, filling it, and starts its refresh. */
    public static View open(JDesktopPane desktop, ChannelData channel) {
        View view = new View(channel);
        desktop.add(view);
        view.setSize(desktop.getSize());
        view.setVisible(true);
        try {
            view.setMaximum(true);
        } catch (PropertyVetoException ignored) {
            // Stays at the desktop's size.
        }
        view.start();
        return view;
    }

    /** An internal frame showing the latest image of one channel. */
    public static class View extends JInternalFrame {
        private static final long serialVersionUID = 1L;
        private final ChannelData channel;
        private final ImagePanel panel = new ImagePanel();
        private final Timer timer;
        private Object shown;  // the message on screen, compared by identity

        View(ChannelData channel) {
            super(channel.name, true, true, true, true);
            this.channel = channel;
            setLayout(new BorderLayout());
            add(panel, BorderLayout.CENTER);
            timer = new Timer(REFRESH_MS, e -> tick());
            addInternalFrameListener(new InternalFrameAdapter() {
                @Override
                public void internalFrameClosed(InternalFrameEvent e) {
                    timer.stop();
                }
            });
        }

        void start() {
            refresh();
            timer.start();
        }

        public ImagePanel panel() {
            return panel;
        }

        /**
         * Shows the channel's latest message if it is new; true if it was.
         * lcm-spy's receive thread replaces channel.last with a new object per
         * message, so identity tells a new frame.
         */
        public boolean refresh() {
            Object last = channel.last;
            if (last == shown) return false;
            shown = last;
            if (last instanceof image_t) {
                panel.setImage((image_t) last);
            } else {
                panel.setImage(null);
            }
            return true;
        }

        private void tick() {
            // lcm-spy hides (does not dispose) its window when it is closed:
            // skip the work while it is hidden.
            Window window = SwingUtilities.getWindowAncestor(this);
            if (window == null || window.isShowing()) refresh();
        }
    }
}
