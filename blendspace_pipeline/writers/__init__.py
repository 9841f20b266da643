"""Writers: clips (BVH, USD, glTF) and blend-space assets (JSON, USD)."""
