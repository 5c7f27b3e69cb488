; prefix_sum: running sum across clusters via the intercluster network.
; s[i] = x[0] + x[1] + ... + x[i] (int32, wrapping), for machines of 1, 2, 4 or 8 clusters.
;
; Each iteration takes one element per cluster (element c of the block in cluster c) and
; scans across clusters (Hillis & Steele): for d = 1, 2, 4, every cluster receives v from
; cluster c - d and adds it if c >= d. Then it adds the carry (the total so far) and
; broadcasts the block's last sum, from cluster C - 1, as the next carry. The sources are
; computed per cluster (`perm[i]` holds c - d, taken modulo the cluster count), so the
; same program runs on any power-of-two cluster count up to 8.
;
; Timing (gold8: stream 3, comm 2, int 2): consumers at least latency + 1 after producers.
kernel prefix_sum
in x
out s

    imm cid -> add0.a[0], add1.b[2]                           ; c
    imm 1 -> add0.b[0], add1.a[2]
    imm 2 -> add0.b[1], add1.a[3]
    imm 4 -> add0.b[2], add1.a[4]
    imm 0 -> add1.b[0], add0.b[4]                             ; zero, and the carry
    imm -1 -> comm0.perm[3]                                   ; -1 mod C = C - 1, the last cluster
    add0 isub a[0], b[0] -> comm0.perm[0] | add1 ile_s a[2], b[2] -> cc[1]     ; c - 1, 1 <= c
    add0 isub a[0], b[1] -> comm0.perm[1] | add1 ile_s a[3], b[2] -> cc[2]     ; c - 2, 2 <= c
    add0 isub a[0], b[2] -> comm0.perm[2] | add1 ile_s a[4], b[2] -> cc[3]     ; c - 4, 4 <= c
loop stream x:
    sin0 x -> comm0.data[0], add0.a[1]                        ; t0: v, lands t3
    nop                                                       ; t1
    nop                                                       ; t2
    nop                                                       ; t3
    comm0 data[0], perm[0] -> add1.a[1]                       ; t4: v of cluster c - 1, lands t6
    nop                                                       ; t5
    nop                                                       ; t6
    add1 select cc[1], a[1], b[0] -> add0.b[3]                ; t7: c >= 1 ? it : 0, lands t9
    nop                                                       ; t8
    nop                                                       ; t9
    add0 iadd a[1], b[3] -> comm0.data[0], add0.a[1]          ; t10: v += it, lands t12
    nop                                                       ; t11
    nop                                                       ; t12
    comm0 data[0], perm[1] -> add1.a[1]                       ; t13: from c - 2
    nop                                                       ; t14
    nop                                                       ; t15
    add1 select cc[2], a[1], b[0] -> add0.b[3]                ; t16
    nop                                                       ; t17
    nop                                                       ; t18
    add0 iadd a[1], b[3] -> comm0.data[0], add0.a[1]          ; t19
    nop                                                       ; t20
    nop                                                       ; t21
    comm0 data[0], perm[2] -> add1.a[1]                       ; t22: from c - 4
    nop                                                       ; t23
    nop                                                       ; t24
    add1 select cc[3], a[1], b[0] -> add0.b[3]                ; t25
    nop                                                       ; t26
    nop                                                       ; t27
    add0 iadd a[1], b[3] -> add0.a[1]                         ; t28: scan of the block, lands t30
    nop                                                       ; t29
    nop                                                       ; t30
    add0 iadd a[1], b[4] -> sout.data[0], comm0.data[1]       ; t31: + carry, lands t33
    nop                                                       ; t32
    nop                                                       ; t33
    sout s, data[0] | comm0 data[1], perm[3] -> add0.b[4]     ; t34: out; carry from cluster C - 1
end
done
