"""Atomic, verified checkpoint units (py/yadecd/checkpoint.py): kills at any moment, damaged and
truncated units, a damaged pointer, a full disk, an unwritable directory.

Pure Python (runs inside YADE with ``bash tests/run.sh`` and with ``/usr/bin/python3 -m unittest``
from tests/).
"""
import errno
import json
import os
import tempfile
import unittest

from repo_package import DATA, REPO, SCRIPTS  # noqa: F401  (first: this checkout's yadecd)
from yadecd.runs import checkpoint as ck





def text_writer(content):
    def write(path):
        with open(path, 'w') as f:
            f.write(content)
    return write


class TestCheckpointStore(unittest.TestCase):
    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.store = ck.CheckpointStore(self.tmp.name)

    def tearDown(self):
        self.tmp.cleanup()

    def write(self, k):
        return self.store.write({'state.txt': text_writer('state %d' % k), 'scene.bin': text_writer('x' * k)},
                                meta={'step': k})

    def read_state(self):
        seq, unit, meta = self.store.latest()
        with open(os.path.join(unit, 'state.txt')) as f:
            return seq, f.read(), meta['meta']['step']

    def test_newest_wins_and_two_are_kept(self):
        for k in range(1, 5):
            self.assertEqual(self.write(k), k)
        self.assertEqual(self.read_state(), (4, 'state 4', 4))
        self.assertEqual(sorted(n for n in os.listdir(self.store.root) if n.isdigit()), ['000003', '000004'])
        with open(os.path.join(self.store.root, 'current.json')) as f:
            self.assertEqual(json.load(f), {'current': 4, 'previous': 3})

    def test_no_checkpoint(self):
        self.assertIsNone(self.store.latest())

    def test_damaged_or_truncated_newest_falls_back(self):
        """A flipped byte or a truncated file in the newest unit: it is skipped with a message
        naming the file, and the previous unit is read."""
        for damage in ('flip', 'truncate', 'delete'):
            self.write(1)
            self.write(2)
            path = os.path.join(self.store.root, '%06d' % 2, 'scene.bin')
            if damage == 'flip':
                with open(path, 'r+b') as f:
                    f.write(b'y')
            elif damage == 'truncate':
                with open(path, 'r+b') as f:
                    f.truncate(1)
            else:
                os.remove(path)
            self.assertEqual(self.read_state()[:2], (1, 'state 1'), damage)
            self.assertIn('checkpoint 2 skipped: scene.bin', self.store.messages[0])
            self.assertIn('moved aside to 000002.damaged', self.store.messages[0])
            self.assertTrue(os.path.isdir(os.path.join(self.store.root, '000002.damaged')))
            self.read_state()
            self.assertEqual(self.store.messages, [], 'a damaged unit is reported once')
            self.assertEqual(self.store.write({'scene.bin': lambda p: open(p, 'w').write('state 3')}), 2)
            for n in os.listdir(self.store.root):          # start again for the next kind of damage
                p = os.path.join(self.store.root, n)
                (os.remove if os.path.isfile(p) else __import__('shutil').rmtree)(p)

    def test_kill_during_write(self):
        """A unit left as .tmp (killed while writing) or written but not yet pointed to (killed
        before the pointer switched): the pointer's unit is still valid; the orphan is verified
        and used only if it is complete; the next write cleans up."""
        self.write(1)
        os.makedirs(os.path.join(self.store.root, '000002.tmp'))
        with open(os.path.join(self.store.root, '000002.tmp', 'state.txt'), 'w') as f:
            f.write('half')
        self.assertEqual(self.read_state()[:2], (1, 'state 1'))
        self.assertEqual(self.write(2), 2)
        self.assertFalse(os.path.exists(os.path.join(self.store.root, '000002.tmp')))
        self.assertEqual(self.read_state()[:2], (2, 'state 2'))

    def test_damaged_pointer(self):
        self.write(1)
        self.write(2)
        with open(os.path.join(self.store.root, 'current.json'), 'w') as f:
            f.write('{"curr')
        self.assertEqual(self.read_state()[:2], (2, 'state 2'))
        self.assertIn('pointer damaged', self.store.messages[0])

    def test_nothing_valid(self):
        self.write(1)
        os.remove(os.path.join(self.store.root, '000001', 'meta.json'))
        with self.assertRaises(ck.CheckpointError) as cm:
            self.store.latest()
        self.assertIn('meta.json unreadable', str(cm.exception))

    def test_full_disk_keeps_the_last_good_one(self):
        """A writer that hits ENOSPC: CheckpointError says the disk is full and names the intact
        checkpoint; no partial unit is left; the next write succeeds."""
        self.write(1)

        def full(path):
            with open(path, 'w') as f:
                f.write('partial')
            raise OSError(errno.ENOSPC, 'No space left on device')
        with self.assertRaises(ck.CheckpointError) as cm:
            self.store.write({'state.txt': full})
        self.assertIn('the disk is full', str(cm.exception))
        self.assertIn('(1) is intact', str(cm.exception))
        self.assertEqual(sorted(os.listdir(self.store.root)), ['000001', 'current.json'])
        self.assertEqual(self.read_state()[:2], (1, 'state 1'))
        self.assertEqual(self.write(2), 2)

    def test_unwritable(self):
        """A writer refused by the file system (EACCES, as in a read-only output directory;
        root ignores directory modes, so the refusal is raised by the writer): a clear error."""
        self.write(1)

        def refused(path):
            raise PermissionError(errno.EACCES, 'Permission denied', path)
        with self.assertRaises(ck.CheckpointError) as cm:
            self.store.write({'state.txt': refused})
        self.assertIn('not writable', str(cm.exception))
        self.assertEqual(self.read_state()[:2], (1, 'state 1'))

    def test_bad_names_and_keep(self):
        with self.assertRaises(ValueError):
            ck.CheckpointStore(self.tmp.name, keep=1)
        with self.assertRaises(ValueError):
            self.store.write({'meta.json': text_writer('x')})


if __name__ == '__main__':
    unittest.main()
