# Copyright 2026 The lookahead_control Authors
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
Regression: a channel defined inside a chunk whose messages are all of known channels.

Found through path_bridge: the recorder met the bridge's topics late and wrote their
channel records into a chunk that held one /rosout message; the column reader trusted
that chunk's message index, never read the definitions, and dropped every later message
of those channels (yaw, velocity, curvature, ground truth: 1 bag in 3).
"""

from lookahead_control.bags import mcap_columns
from mcap.reader import make_reader
from mcap.writer import CompressionType, IndexType, Writer
import pytest


@pytest.mark.parametrize('compression', [CompressionType.NONE, CompressionType.ZSTD])
def test_channels_defined_late_inside_a_chunk_are_read(tmp_path, compression):
    path = tmp_path / 'late.mcap'
    with open(path, 'wb') as stream:
        writer = Writer(stream, chunk_size=1024, compression=compression,
                        index_types=IndexType.ALL)
        writer.start('ros2', 'test')
        schema = writer.register_schema('std_msgs/msg/String', 'ros2msg', b'string data')
        early = writer.register_channel('/early', 'cdr', schema)
        t = 1000
        for _ in range(40):                 # a few chunks of /early only
            t += 1
            writer.add_message(early, t, b'e' * 64, t)
        late = writer.register_channel('/late', 'cdr', schema)     # into the open chunk
        for _ in range(3):                  # that chunk still holds /early messages only
            t += 1
            writer.add_message(early, t, b'e' * 64, t)
        for _ in range(15):                 # chunk(s) further on: /late messages
            for channel in (early, late):
                t += 1
                writer.add_message(channel, t, b'l' * 300, t)
        writer.finish()
    with open(path, 'rb') as stream:
        reference = sum(1 for _, c, _ in make_reader(stream).iter_messages()
                        if c.topic == '/late')
    got = sum(raw.start.size for _, _, raw in mcap_columns.read_columns(path, ['/late']))
    assert reference == 15 and got == 15
