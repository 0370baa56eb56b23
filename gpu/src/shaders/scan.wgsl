// scan.wgsl: the stable compaction's exclusive prefix sum, shared by select.wgsl (over batches),
// hier_select.wgsl (over nodes) and coalesce.wgsl (gpu/src/select.rs SCAN, appended to their
// modules: WGSL has no include); each declares the storage array `offsets: array<u32>` it scans.

var<workgroup> scan_tmp: array<u32, SCAN_WORKGROUP_SIZE>;
var<workgroup> scan_carry: u32;

// Exclusive prefix sum of `offsets[0..n)`, in place, by the dispatch's one workgroup walking the
// array in chunks (Hillis-Steele within a chunk, a running carry across chunks): O(n log 256)
// work, one dispatch. The chunk loop runs n / 256 times: within llvmpipe's 65,535 iterations per
// invocation up to 16 M entries. It has barriers: call it from an entry point, in uniform control
// flow, with a uniform `n`.
fn scan_offsets(lid: u32, n: u32) {
    if lid == 0u {
        scan_carry = 0u;
    }
    workgroupBarrier();
    let chunks = (n + SCAN_WORKGROUP_SIZE - 1u) / SCAN_WORKGROUP_SIZE;
    for (var c = 0u; c < chunks; c++) {
        let index = c * SCAN_WORKGROUP_SIZE + lid;
        var value = 0u;
        if index < n {
            value = offsets[index];
        }
        scan_tmp[lid] = value;
        workgroupBarrier();
        for (var step = 1u; step < SCAN_WORKGROUP_SIZE; step = step << 1u) {
            var add = 0u;
            if lid >= step {
                add = scan_tmp[lid - step];
            }
            workgroupBarrier();
            scan_tmp[lid] = scan_tmp[lid] + add;
            workgroupBarrier();
        }
        let carry = scan_carry;
        if index < n {
            offsets[index] = carry + scan_tmp[lid] - value;
        }
        workgroupBarrier();
        if lid == SCAN_WORKGROUP_SIZE - 1u {
            scan_carry = carry + scan_tmp[lid];
        }
        workgroupBarrier();
    }
}
