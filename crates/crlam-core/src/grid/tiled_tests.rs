//! Tests of the tiled storage and its tile pool.

use super::*;

fn geom() -> GridGeometry {
    GridGeometry::new([0.0, 0.0], 0.5).unwrap()
}

#[test]
fn dropped_grids_lend_their_tiles_to_the_copies_of_their_family() {
    let rect = CellRect {
        ix0: 0,
        iy0: 0,
        nx: 16,
        ny: 16,
    };
    let mut a = TiledGrid::new(geom(), 8, &[1.0f32, 2.0], None).unwrap();
    a.reserve(rect).unwrap();
    a.get_mut(1, 1).unwrap()[0] = 5.0;
    // A clone writes: its tile is a copy, freed to the pool when the clone is dropped.
    let mut b = a.clone();
    b.get_mut(2, 2).unwrap()[1] = 7.0;
    b.get_mut(12, 12).unwrap()[0] = 9.0;
    let b_tiles: Vec<usize> = b.tile_addresses().map(|(p, _)| p).collect();
    let a_tiles: Vec<usize> = a.tile_addresses().map(|(p, _)| p).collect();
    drop(b);
    assert_eq!(a.pool.lock().len(), 2, "both of b's own tiles are pooled");
    // Another clone reuses them: a copy of a's tile and a never-written tile from the fill,
    // with none of b's values left in either.
    let mut c = a.clone();
    c.get_mut(3, 3).unwrap()[0] = 4.0;
    c.get_mut(9, 1).unwrap()[0] = 6.0;
    assert!(a.pool.lock().is_empty());
    for (p, _) in c.tile_addresses() {
        assert!(b_tiles.contains(&p) && !a_tiles.contains(&p));
    }
    for iy in 0..16 {
        for ix in 0..16 {
            if (ix, iy) != (3, 3) && (ix, iy) != (9, 1) {
                assert_eq!(c.get(ix, iy), a.get(ix, iy), "cell ({ix}, {iy})");
            }
        }
    }
    assert_eq!(c.get(1, 1), &[5.0, 2.0]);
    assert_eq!(c.get(2, 2), &[1.0, 2.0]);
    assert_eq!(c.get(3, 3), &[4.0, 2.0]);
    assert_eq!(c.get(9, 1), &[6.0, 2.0]);
    assert_eq!(c.get(12, 12), &[1.0, 2.0]);
    assert_eq!(a.get(3, 3), &[1.0, 2.0]);
    // The last grid of a family keeps nothing back.
    drop(c);
    let n = a.pool.lock().len();
    assert_eq!(n, 2);
    drop(a);
}

#[test]
fn unwritten_cells_read_fill_and_growth_keeps_data() {
    let mut g = TiledGrid::new(geom(), 8, &[1.0f32, 2.0], None).unwrap();
    assert_eq!(g.get(100, -100), &[1.0, 2.0]);
    g.reserve(CellRect {
        ix0: 0,
        iy0: 0,
        nx: 1,
        ny: 1,
    })
    .unwrap();
    g.get_mut(3, 4).unwrap()[1] = 7.0;
    g.reserve(CellRect {
        ix0: -100,
        iy0: 50,
        nx: 1,
        ny: 1,
    })
    .unwrap();
    g.get_mut(-100, 50).unwrap()[0] = 9.0;
    assert_eq!(g.get(3, 4), &[1.0, 7.0]);
    assert_eq!(g.get(-100, 50), &[9.0, 2.0]);
    assert_eq!(g.tile_stats().n_allocated, 2);
}

#[test]
fn clones_share_tiles_until_written() {
    let mut a = TiledGrid::new(geom(), 8, &[0.0f32], None).unwrap();
    a.reserve(CellRect {
        ix0: 0,
        iy0: 0,
        nx: 64,
        ny: 64,
    })
    .unwrap();
    for i in 0..64 {
        a.get_mut(i, i).unwrap()[0] = i as f32;
    }
    let mut b = a.clone();
    assert_eq!(b.tile_stats().n_shared, 8);
    b.get_mut(0, 0).unwrap()[0] = -1.0;
    assert_eq!(a.get(0, 0), &[0.0]);
    assert_eq!(b.get(0, 0), &[-1.0]);
    assert_eq!(b.tile_stats().n_shared, 7);
    assert_eq!(a.get(9, 9), b.get(9, 9));
}

#[test]
fn fixed_extent_refuses_outside_writes() {
    let r = CellRect {
        ix0: 0,
        iy0: 0,
        nx: 10,
        ny: 10,
    };
    let mut g = TiledGrid::new(geom(), 8, &[0u8], Some(r)).unwrap();
    assert!(g.get_mut(9, 9).is_ok());
    assert!(g.get_mut(10, 0).is_err());
    assert!(g
        .reserve(CellRect {
            ix0: 5,
            iy0: 5,
            nx: 10,
            ny: 1
        })
        .is_err());
    assert_eq!(g.bounds(), r);
}

#[test]
fn export_import_round_trip() {
    let mut g = TiledGrid::new(geom(), 4, &[0i32, 0], None).unwrap();
    let r = CellRect {
        ix0: -3,
        iy0: 2,
        nx: 5,
        ny: 3,
    };
    let vals: Vec<i32> = (0..30).collect();
    g.import(r, &vals).unwrap();
    assert_eq!(g.export(r).unwrap(), vals);
}

#[test]
fn bad_config_is_an_error() {
    assert!(GridGeometry::new([0.0, 0.0], 0.0).is_err());
    assert!(TiledGrid::new(geom(), 7, &[0u8], None).is_err());
}
