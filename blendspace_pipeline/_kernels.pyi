from _typeshed import ReadableBuffer, WriteableBuffer

def parse_decimals(block: ReadableBuffer, out: WriteableBuffer, frames: int, channels: int, /) -> bool: ...
def forward_kinematics(
    local_rot: ReadableBuffer,
    local_pos: ReadableBuffer,
    parents: ReadableBuffer,
    world_rot: WriteableBuffer,
    world_pos: WriteableBuffer,
    frames: int,
    /,
) -> bool: ...
def slerp(
    a: ReadableBuffer, b: ReadableBuffer, t: ReadableBuffer, out: WriteableBuffer, count: int, /
) -> bool: ...
