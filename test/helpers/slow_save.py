"""
Save a hairstyle with an fsync that stalls, so a test can kill the process mid-save.

argv: style_path target_path
"""

import os
import sys
import time

from hair_sim.modeling import load_hairstyle, save_hairstyle, yamlio


def stalled_fsync(fd):
    """Stand in for a slow disk: announce, then hang before the data is durable."""
    print('writing', flush=True)
    time.sleep(60)


def main():
    """Load a style, rename it, and save it over the target with a hanging fsync."""
    style = load_hairstyle(sys.argv[1]).derive('half_written')
    yamlio.os.fsync = stalled_fsync
    save_hairstyle(style, sys.argv[2])
    os._exit(0)


if __name__ == '__main__':
    main()
